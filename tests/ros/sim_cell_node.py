"""The simulated cell as a node (#31): `waam sim-cell --node` gives `waam node` its sensors.

waam node runs as /cellZ/waam_planner, a dry run at 20 times real time with the closed loop
on (tests/ros/closed_loop_execute.params.yaml); `waam sim-cell tests/data/twin-walls.yaml
--truth docs/examples/closed-loop/truth.yaml --node --thermal-camera --time-scale 20` runs
beside it in /cellZ (a cell with 25 % lower heat losses whose beads come out 10 % low). rclpy
only sends the part and the ~/execute goal: the temperatures, thermal images and scans come
from the simulated cell.

It checks: the execution succeeds; at the first weld-path boundary the `replanned` status
counts readings used (> 0), fits a loss factor between 0.6 and 0.9 and re-plans the windowed
wall still to come (`reason: replan`); the scans the node took show the layers' true tops
(2.25 mm a layer, at the nominal feed); the thermal camera's images were used (every welded
block read); a wire feed went out before each weld path, within the limits, with its
schedule (one feed per deposit, the first the one struck at) on ~/wire_feed_schedule, and
any revision of it while the arc was on within the limits too.
"""

import sys

from diagnostic_msgs.msg import DiagnosticArray
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory

import waamtest
from waamtest import check

NS = "/cellZ/waam_planner"


def statuses(peer, state):
    return waamtest.statuses(peer, NS + "/status", state)


def sensor(peer, name):
    return [s for a in peer.received["/diagnostics"] for s in a.status
            if s.name == f"cellZ/waam_planner: {name} sensor"]


def test(peer, waam):
    waamtest.beside_the_simulated_cell(peer, run, "tests/data/twin-walls.yaml",
                                       "--truth", "docs/examples/closed-loop/truth.yaml", "--node",
                                       "--thermal-camera",
                                       "--time-scale", "20", "--ros-args", "-r", "__ns:=/cellZ")


def run(peer, cell):
    peer.listen("/diagnostics", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    feeds = []
    peer.node.create_subscription(Float64, NS + "/wire_feed", lambda m: feeds.append(m.data),
                                  waamtest.INPUT_QOS)
    schedules = []
    peer.node.create_subscription(JointTrajectory, NS + "/wire_feed_schedule",
                                  schedules.append, waamtest.INPUT_QOS)
    waamtest.execute_beside_the_simulated_cell(peer, NS, cell)

    waamtest.check_replanned_on_lower_losses(peer, NS + "/status")

    # A wire feed before each weld path (at least the two of the first plan), the first
    # nominal (nothing scanned yet), all within the process limits.
    peer.spin_for(1.0)
    print(f"wire feeds: {feeds}")
    check(len(feeds) >= 2 and feeds[0] == 1.0 and all(0.7 <= f <= 1.3 for f in feeds),
          f"wire feeds: {feeds}")
    # Each weld path's schedule: joint "wire_feed", a point per deposit from the arc strike
    # on, starting with the feed struck at; a revision while the arc is on (a layer scanned
    # mid-path) starts at a later deposit.
    check(all(s.joint_names == ["wire_feed"] and len(s.points) >= 1 for s in schedules),
          f"wire feed schedules: {schedules}")
    struck = [s for s in schedules if s.points[0].time_from_start.sec == 0
              and s.points[0].time_from_start.nanosec == 0]
    per_path = [[p.positions[0] for p in s.points] for s in struck]
    revised = len(schedules) - len(struck)
    print(f"wire feed schedules: {[[round(f, 3) for f in s] for s in per_path]}, "
          f"{revised} revised while the arc was on")
    check(len(struck) == len(feeds)
          and all(s[0] == f for s, f in zip(per_path, feeds))
          and all(0.7 <= p.positions[0] <= 1.3 for s in schedules for p in s.points),
          f"wire feed schedules {per_path} against the feeds {feeds}")
    # The scanner saw the finished layers 10 % low: tops at multiples of 2.25 mm.
    scans = [s.message for s in sensor(peer, "scan") if "top at" in s.message]
    print(f"scans: {sorted(set(scans))}")
    tops = {float(m.split("top at ")[1].split(" mm")[0]) for m in scans}
    check(tops and all(abs(t / 2.25 - round(t / 2.25)) < 0.01 for t in tops),
          f"scanned tops {sorted(tops)} mm are not those of 2.25 mm layers")
    # The camera's images were used: each reads every block welded by then.
    images = [s.message for s in sensor(peer, "thermal camera") if "points read" in s.message]
    print(f"thermal images: {len(images)}, last: {images[-1] if images else None}")
    read = [int(m.split(": ")[-1].split(" points read")[0]) for m in images]
    check(read and max(read) > 1, f"no thermal image used: {images[:3]}")
    check(cell.alive(), "the simulated cell exited")


# The node records to the directory given (argument 1): `waam replay` re-runs its decisions.
waamtest.run(test, "node", "--dry-run", "--params", "tests/ros/closed_loop_execute.params.yaml",
             "--record", sys.argv[1], "--ros-args", "-r", "__ns:=/cellZ")
