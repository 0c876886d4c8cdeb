"""Published sensor readings reach the node's closed loop (#31).

waam node runs as /cellY/waam_planner (`-r __ns:=/cellY`), a dry run at 10 times real time
with `closed_loop.enabled: true` (tests/ros/closed_loop_execute.params.yaml, its time scale
set to 10), recording into the directory given as the first argument (tests/cli/ros_node.rs
checks the recording). rclpy sends tests/data/twin-walls.yaml on ~/part, runs it through
~/execute and, while ~/arc_on is true, publishes pyrometer readings on ~/temperature at about
200 Hz with the sensor-data QoS (best effort), and a scan of the tall wall's top on ~/scan.

The readings are of a cell with 25 % lower heat losses than the part's model: the second
argument is a JSON file of its first weld path, each deposit's block and true temperature at
the end of the deposit, computed in Rust with the project's simulator (as
crates/ros/tests/closed_loop.rs's `Cell1` does). The script checks that the node's plan
(~/plan/weld_plan) welds those blocks first, and times each reading by it: at `time_scale`
10, deposit j is under the torch from (start_j - start_0) / 10 after `~/arc_on` turns true, and
its readings are stamped in its middle.

It checks: the `replanned` status at the boundary counts readings used (> 0) and a loss
factor between 0.6 and 0.9 (the truth's is 0.75); the ~/execute goal succeeds; a wire feed
came on ~/wire_feed before each weld path, within the process limits; the temperature sensor
is OK on /diagnostics. The node is told the cell has a thermal camera publishing every 0.5 s
(`closed_loop.thermal_camera_period_s`), which stays silent: /diagnostics must say so (WARN)
while the execution runs, and no longer once it is over.
"""

import bisect
import json
import struct
import sys
import time

import rclpy

from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.action import ActionClient
from rclpy.qos import qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2, PointField, Temperature
from std_msgs.msg import Bool, Float64, String
from waam_interfaces.action import ExecutePlan
from waam_interfaces.msg import WeldPlan

import waamtest
from waamtest import check

NS = "/cellY/waam_planner"
TIME_SCALE = 10.0  # dry_run.time_scale, set below
# The tall wall (row y = 2 of 6 mm blocks, 4 layers of 2.5 mm): its top along the centre line.
TALL_TOP = [(0.003 + 0.006 * i, 0.015, 0.010) for i in range(6)]


def now(peer):
    t = peer.node.get_clock().now().nanoseconds
    return Time(sec=t // 10**9, nanosec=t % 10**9)


def reading(stamp_ns, celsius):
    msg = Temperature(temperature=celsius, variance=0.0)
    msg.header.stamp = Time(sec=stamp_ns // 10**9, nanosec=stamp_ns % 10**9)
    msg.header.frame_id = "pyrometer"
    return msg


def cloud(peer, points):
    msg = PointCloud2()
    msg.header.stamp = now(peer)
    msg.header.frame_id = "part"
    msg.height, msg.width = 1, len(points)
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate("xyz")]
    msg.point_step, msg.row_step = 12, 12 * len(points)
    msg.data = b"".join(struct.pack("<3f", *p) for p in points)
    msg.is_dense = True
    return msg


def statuses(peer, state):
    return waamtest.statuses(peer, NS + "/status", state)


def test(peer, waam):
    peer.listen("/diagnostics", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/plan/weld_plan", WeldPlan)
    with open(sys.argv[2]) as f:
        truth = json.load(f)
    # The arc's switches, each with when the node published it (the DDS source timestamp,
    # on the node's clock): the strike's time, however late it reaches this script.
    arc = []
    peer.node.create_subscription(
        Bool, NS + "/arc_on", lambda m, info: arc.append((m.data, info["source_timestamp"])),
        waamtest.INPUT_QOS)
    feeds = []
    peer.node.create_subscription(Float64, NS + "/wire_feed", lambda m: feeds.append(m.data),
                                  waamtest.INPUT_QOS)
    part = peer.publisher(NS + "/part", String)
    scan = peer.publisher(NS + "/scan", PointCloud2, qos=qos_profile_sensor_data)
    temperature = peer.publisher(NS + "/temperature", Temperature, qos=qos_profile_sensor_data)
    for p in (part, scan, temperature):
        peer.wait_for_subscriber(p)
    execute = ActionClient(peer.node, ExecutePlan, NS + "/execute")
    if not execute.wait_for_server(timeout_sec=30):
        raise waamtest.DiscoveryTimeout("no ~/execute action server after 30 s")

    result = waamtest.plan_then_execute(peer, part, execute, NS + "/status",
                                        "tests/data/twin-walls.yaml", ExecutePlan.Goal)

    # Deposit j of the first weld path starts at starts[j] on the plan's time line.
    peer.spin_until("the weld plan", lambda: peer.received[NS + "/plan/weld_plan"], 30)
    plan = peer.received[NS + "/plan/weld_plan"][-1]
    blocks = [[b.x, b.y, b.z] for b in plan.fragments[0].blocks]
    check(blocks == [d["block"] for d in truth],
          f"the node's first weld path {blocks} is not the one the truth is of")
    starts = [min(p.time_from_start.sec + p.time_from_start.nanosec * 1e-9
                  for p in plan.points if p.fragment == 0 and p.block == j and p.arc_on)
              for j in range(len(blocks))]

    # Readings at 200 Hz while the arc is on (a 1 s deposit lasts 0.1 s at time_scale 10),
    # on the first weld path the true temperature of the deposit under the torch, timed from
    # the strike and stamped in the middle of that deposit: on a busy machine a reading sent
    # late is still read on the deposit it is of. A scan with every 20th.
    ends = starts[1:] + [starts[-1] + (starts[-1] - starts[-2])]
    sent_t = sent_s = 0
    start = time.monotonic()
    arc_on_s = 0.0
    tick = 0
    arcs_on = 0
    lit = None  # when the arc last struck: (monotonic, ROS clock in ns)
    while not result.done() and time.monotonic() < start + 180:
        if arc and arc[-1][0]:
            if lit is None:
                struck = arc[-1][1]
                ago = (peer.node.get_clock().now().nanoseconds - struck) * 1e-9
                lit = (time.monotonic() - ago, struck)
                arcs_on += 1
            if arcs_on == 1:
                t = starts[0] + (time.monotonic() - lit[0]) * TIME_SCALE
                j = max(0, bisect.bisect_right(starts, t) - 1)
                mid = ((starts[j] + ends[j]) / 2 - starts[0]) / TIME_SCALE
                temperature.publish(reading(lit[1] + int(mid * 1e9), truth[j]["celsius"]))
                sent_t += 1
                arc_on_s += 0.005
                if sent_t % 20 == 0:
                    scan.publish(cloud(peer, TALL_TOP))
                    sent_s += 1
        else:
            lit = None
        rclpy.spin_once(peer.node, timeout_sec=0)
        tick += 1
        time.sleep(max(0.0, start + tick * 0.005 - time.monotonic()))
    check(result.done(), "~/execute did not end within 180 s")
    r = result.result()
    check(r.status == GoalStatus.STATUS_SUCCEEDED
          and r.result.outcome == ExecutePlan.Result.EXECUTED,
          f"~/execute: status {r.status}, {r.result}")
    print(f"~/execute: {r.result.message!r}; {sent_t} temperatures ({sent_t / arc_on_s:.0f} Hz "
          f"on the first weld path) and {sent_s} scans sent")

    waamtest.check_replanned_on_lower_losses(peer, NS + "/status")
    plans = [[[(b.x, b.y, b.z) for b in f.blocks] for f in p.fragments]
             for p in peer.received[NS + "/plan/weld_plan"]]
    check(len(plans) >= 2 and plans[-1] != plans[0] and plans[-1][0] == plans[0][0],
          f"no new plan after the first weld path: {len(plans)} weld plan(s) received")
    print(f"new plan: {len(plans[-1])} weld paths after the re-plan, {len(plans[0])} before")

    # A wire feed before each weld path, within the process limits (0.7..1.3 x nominal), the
    # first nominal: no layer was scanned yet.
    peer.spin_for(1.0)
    switches = [on for on, _ in arc]
    welds = sum(1 for a, b in zip([False] + switches, switches) if b and not a)
    print(f"wire feeds: {feeds} for {welds} weld paths")
    check(len(feeds) == welds and feeds and feeds[0] == 1.0
          and all(0.7 <= f <= 1.3 for f in feeds), f"wire feeds {feeds} for {welds} weld paths")

    # The temperature sensor's last word on /diagnostics is OK.
    def sensor(array):
        return [s for s in array.status if s.name == "cellY/waam_planner: temperature sensor"]

    peer.spin_until("a temperature sensor status", lambda: any(
        sensor(a) for a in peer.received["/diagnostics"]), 10)
    last = [sensor(a)[0] for a in peer.received["/diagnostics"] if sensor(a)][-1]
    check(waamtest.level(last) == 0, f"temperature sensor: {last.message}")
    print(f"temperature sensor: {last.message}")

    # The camera never published: silent for longer than its cadence while executing.
    camera = [s for a in peer.received["/diagnostics"] for s in a.status
              if s.name == "cellY/waam_planner: thermal camera sensor"]
    silent = [s.message for s in camera if waamtest.level(s) == 1 and "silent: no message" in s.message]
    print(f"thermal camera: {silent[:1]}")
    check(silent and "thermal_camera_period_s" in silent[0],
          f"the silent camera was not reported: {[s.message for s in camera][-3:]}")
    # Once the execution is over, silence is no news: OK (no data yet) again.
    peer.spin_for(1.5)
    camera = [s for a in peer.received["/diagnostics"] for s in a.status
              if s.name == "cellY/waam_planner: thermal camera sensor"]
    check(waamtest.level(camera[-1]) == 0, f"after the execution: {camera[-1].message}")
    check(waam.alive(), "waam node exited")


waamtest.run(test, "node", "--dry-run", "--params", "tests/ros/closed_loop_execute.params.yaml",
             "--record", sys.argv[1], "--ros-args", "-r", "__ns:=/cellY",
             "-p", "closed_loop.thermal_camera_period_s:=0.5",
             "-p", f"dry_run.time_scale:={TIME_SCALE}")
