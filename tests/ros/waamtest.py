"""Shared helpers of the ROS 2 interop tests: start `waam node`, wait for messages, fail clearly.

Every test script runs inside its own network namespace (see netns.sh) or, where that is not
possible, on loopback-only discovery with its own ROS_DOMAIN_ID; the Rust test runner sets
WAAM_BIN (the binary under test), ROS_DOMAIN_ID and ROS_AUTOMATIC_DISCOVERY_RANGE.
"""

import os
import subprocess
import sys
import tempfile
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

# Inputs of waam_planner: Reliable, Volatile, depth 10.
INPUT_QOS = QoSProfile(
    depth=10, history=HistoryPolicy.KEEP_LAST, reliability=ReliabilityPolicy.RELIABLE
)
# Outputs of waam_planner: Reliable, TransientLocal, depth 1 (latched).
LATCHED_QOS = QoSProfile(
    depth=1,
    history=HistoryPolicy.KEEP_LAST,
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.TRANSIENT_LOCAL,
)

REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))


def level(status):
    """A DiagnosticStatus level as an int (rclpy gives `byte` fields as bytes)."""
    return status.level if isinstance(status.level, int) else status.level[0]


def box_mesh(sx, sy, sz):
    """A closed, outward-facing box with one corner at the origin (metres)."""
    from geometry_msgs.msg import Point
    from shape_msgs.msg import Mesh, MeshTriangle

    v = [(x * sx, y * sy, z * sz) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
    # Vertex index = x + 2y + 4z; two triangles per face, counter-clockwise from outside.
    faces = [
        (0, 2, 3, 1),  # bottom (z=0), normal -z
        (4, 5, 7, 6),  # top, +z
        (0, 1, 5, 4),  # y=0, -y
        (2, 6, 7, 3),  # y=1, +y
        (0, 4, 6, 2),  # x=0, -x
        (1, 3, 7, 5),  # x=1, +x
    ]
    tris = []
    for a, b, c, d in faces:
        tris += [(a, b, c), (a, c, d)]
    return Mesh(
        vertices=[Point(x=x, y=y, z=z) for x, y, z in v],
        triangles=[MeshTriangle(vertex_indices=list(t)) for t in tris],
    )


def ring_mesh(r_in, r_out, height, n=128):
    """A closed tube around the origin (metres), n segments, outward-facing triangles."""
    import math

    from geometry_msgs.msg import Point
    from shape_msgs.msg import Mesh, MeshTriangle

    # Vertex index = i + n * (wall + 2 * level): wall 0 inner, 1 outer; level 0 bottom, 1 top.
    v = [
        (r * math.cos(2 * math.pi * i / n), r * math.sin(2 * math.pi * i / n), z)
        for z in (0.0, height)
        for r in (r_in, r_out)
        for i in range(n)
    ]

    def at(level, wall, i):
        return (i % n) + n * (wall + 2 * level)

    tris = []
    for i in range(n):
        j = i + 1
        tris += [
            (at(0, 1, i), at(0, 1, j), at(1, 1, j)), (at(0, 1, i), at(1, 1, j), at(1, 1, i)),  # outer
            (at(0, 0, i), at(1, 0, j), at(0, 0, j)), (at(0, 0, i), at(1, 0, i), at(1, 0, j)),  # inner
            (at(1, 0, i), at(1, 1, i), at(1, 1, j)), (at(1, 0, i), at(1, 1, j), at(1, 0, j)),  # top
            (at(0, 0, i), at(0, 1, j), at(0, 1, i)), (at(0, 0, i), at(0, 0, j), at(0, 1, j)),  # bottom
        ]
    return Mesh(
        vertices=[Point(x=x, y=y, z=z) for x, y, z in v],
        triangles=[MeshTriangle(vertex_indices=list(t)) for t in tris],
    )


def fit_circle(points):
    """Least-squares circle through (x, y) points (Kasa's fit): (cx, cy, r)."""
    # x^2 + y^2 = 2 cx x + 2 cy y + c: a 3x3 normal-equation solve by Cramer's rule.
    rows = [(2 * x, 2 * y, 1.0, x * x + y * y) for x, y in points]
    a = [[sum(r[i] * r[j] for r in rows) for j in range(3)] for i in range(3)]
    b = [sum(r[i] * r[3] for r in rows) for i in range(3)]

    def det(m):
        return (m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
                - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
                + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0]))

    d = det(a)
    cx, cy, c = (det([[b[i] if k == col else a[i][k] for k in range(3)] for i in range(3)]) / d
                 for col in range(3))
    return cx, cy, (c + cx * cx + cy * cy) ** 0.5


class Failure(Exception):
    pass


class DiscoveryTimeout(Failure):
    """A peer that never showed up: DDS discovery, not the node's behaviour. Printed as
    `FAIL (discovery): ...`, which tests/cli/ros_node.rs retries once in a fresh domain."""

    def __str__(self):
        return f"(discovery) {super().__str__()}"


def check(condition, message):
    if not condition:
        raise Failure(message)


def values(status):
    """A DiagnosticStatus's key-values as a dict."""
    return {kv.key: kv.value for kv in status.values}


def statuses(peer, topic, state):
    """The key-values of every status in `state` the peer received on `topic` (a node's
    ~/status, listened to)."""
    return [values(s) for a in peer.received[topic] for s in a.status
            if values(s).get("state") == state]


def plan_then_execute(peer, part, execute, status_topic, path, goal_type):
    """Publishes the part file `path` (relative to the repository) on `part`, waits until the
    node on `status_topic` planned it, and sends its job to the ~/execute client `execute`;
    returns the result future of the accepted goal."""
    with open(f"{REPO}/{path}") as f:
        part.publish(String(data=f.read()))
    peer.spin_until(f"{path} planned", lambda: statuses(peer, status_topic, "planned"), 120)
    job = int(statuses(peer, status_topic, "planned")[-1]["job"])
    sent = execute.send_goal_async(goal_type(job=job))
    # No answer at all within 30 s is discovery: `wait_for_server` says only that the
    # node's request reader was found, and an answer the node sends before it has found
    # this client's reply reader is lost (seen once with a parameter service on CI).
    peer.spin_until("the ~/execute goal accepted", sent.done, 30, discovery=True)
    check(sent.result().accepted, "the ~/execute goal was rejected")
    return sent.result().get_result_async()


def beside_the_simulated_cell(peer, check_run, *args):
    """Starts `waam sim-cell ARGS` (its node), runs `check_run(peer, cell)`, stops the cell
    and prints its log (also when the check fails)."""
    cell = WaamProcess("sim-cell", *args)
    try:
        check_run(peer, cell)
    finally:
        cell.stop()
        print(f"--- log of the simulated cell ---\n{cell.output()}")


def execute_beside_the_simulated_cell(peer, ns, cell, path="tests/data/twin-walls.yaml"):
    """Sends the part file `path` to node `ns` (its ~/part), once its ~/execute server and
    the simulated cell's node `cell` (a WaamProcess) are up, runs it through ~/execute and
    checks the execution succeeded."""
    from action_msgs.msg import GoalStatus
    from rclpy.action import ActionClient
    from waam_interfaces.action import ExecutePlan

    part = peer.publisher(ns + "/part", String)
    peer.wait_for_subscriber(part)
    execute = ActionClient(peer.node, ExecutePlan, ns + "/execute")
    if not execute.wait_for_server(timeout_sec=30):
        raise DiscoveryTimeout("no ~/execute action server after 30 s")
    # The simulated cell follows the planner's topics: wait until it is discovered.
    peer.spin_until("the simulated cell's node",
                    lambda: "waam_sim_cell" in peer.node.get_node_names(), 30, discovery=True)
    check(cell.alive(), "the simulated cell exited")
    result = plan_then_execute(peer, part, execute, ns + "/status", path, ExecutePlan.Goal)
    peer.spin_until("~/execute done", result.done, 180)
    r = result.result()
    check(r.status == GoalStatus.STATUS_SUCCEEDED
          and r.result.outcome == ExecutePlan.Result.EXECUTED,
          f"~/execute: status {r.status}, {r.result}")


def check_replanned_on_lower_losses(peer, topic):
    """The closed loop's first boundary on a cell with 25 % lower heat losses than the model,
    as `topic` (a node's ~/status) told it: readings used, a loss factor fitted between 0.6
    and 0.9, and the rest re-planned. Returns that status."""
    peer.spin_until("a replanned status", lambda: statuses(peer, topic, "replanned"), 10)
    for s in statuses(peer, topic, "replanned"):
        print(f"replanned: {s}")
    first = statuses(peer, topic, "replanned")[0]
    check(int(first["readings_used"]) > 0, f"no reading reached the loop: {first}")
    check(0.6 < float(first["loss_factor"]) < 0.9,
          f"25 % lower losses, yet a loss factor of {first['loss_factor']}: {first}")
    check(first["reason"] == "replan", f"the boundary did not re-plan: {first}")
    return first


class WaamProcess:
    """`waam ARGS` as a child process, its log kept in a file and shown when a test fails."""

    def __init__(self, *args):
        self.log = tempfile.NamedTemporaryFile(prefix="waam-", suffix=".log", delete=False)
        env = dict(os.environ)
        self.args = [os.environ["WAAM_BIN"], *args]
        self.proc = subprocess.Popen(
            self.args, stdout=self.log, stderr=subprocess.STDOUT, env=env, cwd=REPO
        )

    def alive(self):
        return self.proc.poll() is None

    def wait(self, timeout):
        return self.proc.wait(timeout=timeout)

    def stop(self):
        if self.alive():
            self.proc.terminate()
            try:
                self.proc.wait(timeout=10)
            except subprocess.TimeoutExpired:
                self.proc.kill()
                self.proc.wait()

    def output(self):
        self.log.flush()
        with open(self.log.name, encoding="utf-8", errors="replace") as f:
            return f.read()


class Peer:
    """An rclpy node that collects what it hears on named topics."""

    def __init__(self, name="waam_test_peer"):
        rclpy.init()
        self.node = Node(name)
        self.received = {}

    def listen(self, topic, msg_type, qos=LATCHED_QOS, raw=False):
        self.received[topic] = []
        self.node.create_subscription(
            msg_type, topic, lambda m: self.received[topic].append(m), qos, raw=raw
        )

    def publisher(self, topic, msg_type, qos=INPUT_QOS):
        return self.node.create_publisher(msg_type, topic, qos)

    def spin_until(self, what, condition, timeout, discovery=False):
        """Spins until condition() is true; fails naming `what` after `timeout` seconds
        (with DiscoveryTimeout when what is awaited is a peer's endpoint: `discovery`
        true, or a function that says so at the timeout)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if condition():
                return
            rclpy.spin_once(self.node, timeout_sec=0.1)
        if not condition():
            if callable(discovery):
                discovery = discovery()
            failure = DiscoveryTimeout if discovery else Failure
            raise failure(f"timed out after {timeout} s waiting for {what}")

    def spin_for(self, seconds):
        deadline = time.monotonic() + seconds
        while time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=0.05)

    def wait_for_subscriber(self, publisher, timeout=30):
        self.spin_until(
            f"a subscriber on {publisher.topic_name}",
            lambda: publisher.get_subscription_count() > 0,
            timeout,
            discovery=True,
        )

    def close(self):
        self.node.destroy_node()
        rclpy.shutdown()


def run(test, *waam_args):
    """Runs `test(peer, waam)` with `waam ARGS` started first; exits 0 on success, 1 on
    failure with the reason and the waam log."""
    waam = WaamProcess(*waam_args)
    peer = Peer()
    try:
        test(peer, waam)
    except Failure as e:
        print(f"FAIL{' ' if isinstance(e, DiscoveryTimeout) else ': '}{e}", file=sys.stderr)
        print(f"--- log of {' '.join(waam.args)} ---\n{waam.output()}", file=sys.stderr)
        sys.exit(1)
    finally:
        waam.stop()
        peer.close()
    print(f"--- log of {' '.join(waam.args)} ---\n{waam.output()}")
    print("PASS")
