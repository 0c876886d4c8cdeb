"""Wire feeds revised while the arc is on (#31): `waam sim-cell --node` (beads 10 % low, the
scanner behind the torch scanning each layer as it is finished) beside `waam node`
(/cellS/waam_planner, a dry run at 20 times real time, closed loop on), on
tests/data/square-tube-spiral.yaml: one weld path that goes round each layer and climbs to
the next, so its feeds are all set at the arc strike, before any layer is scanned. rclpy only
sends the part and the ~/execute goal.

It checks: the execution succeeds; the weld path's schedule at the strike is nominal; while
its arc is on the node sends revisions of it (~/wire_feed_schedule whose first point is after
the strike) raising feeds within the limits; the scan of the top layer shows it within 0.5 mm
of the nominal 10 mm (a node that only sets feeds at the strike ends it at 9 mm); a
`replanned` status with reason `finished` records the revisions.
"""

import sys

from diagnostic_msgs.msg import DiagnosticArray
from trajectory_msgs.msg import JointTrajectory

import waamtest
from waamtest import check

NS = "/cellS/waam_planner"
PART = "tests/data/square-tube-spiral.yaml"


def test(peer, waam):
    waamtest.beside_the_simulated_cell(peer, run, PART,
                                       "--truth", "docs/examples/closed-loop/truth.yaml",
                                       "--node", "--time-scale", "20",
                                       "--ros-args", "-r", "__ns:=/cellS")


def after_strike(schedule):
    t = schedule.points[0].time_from_start
    return t.sec > 0 or t.nanosec > 0


def run(peer, cell):
    peer.listen("/diagnostics", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    schedules = []
    peer.node.create_subscription(JointTrajectory, NS + "/wire_feed_schedule",
                                  schedules.append, waamtest.INPUT_QOS)
    waamtest.execute_beside_the_simulated_cell(peer, NS, cell, PART)
    peer.spin_for(1.0)

    feeds = [[round(p.positions[0], 3) for p in s.points] for s in schedules]
    print(f"wire feed schedules: {feeds}")
    struck = [s for s in schedules if not after_strike(s)]
    revised = [s for s in schedules if after_strike(s)]
    check(len(struck) == 1 and len(struck[0].points) == 48
          and all(p.positions[0] == 1.0 for p in struck[0].points),
          f"one weld path of 48 deposits struck at the nominal feed: {feeds}")
    check(revised and all(0.7 <= p.positions[0] <= 1.3 for s in revised for p in s.points)
          and any(p.positions[0] > 1.0 for s in revised for p in s.points),
          f"no revision raising the feeds while the arc was on: {feeds}")

    scans = [s.message for a in peer.received["/diagnostics"] for s in a.status
             if s.name == "cellS/waam_planner: scan sensor" and "top at" in s.message]
    tops = [float(m.split("top at ")[1].split(" mm")[0]) for m in scans]
    print(f"scanned tops: {tops}")
    # /diagnostics reports the latest scan now and then: the last, the top layer's.
    check(tops and abs(tops[-1] - 10.0) <= 0.5,
          f"the top layer's scan {tops} is not within 0.5 mm of 10 mm")

    finished = [s for s in waamtest.statuses(peer, NS + "/status", "replanned")
                if s.get("reason") == "finished"]
    check(len(finished) == 1 and "loop.feed_revisions" in finished[0],
          f"no finished record of the revisions: {finished}")
    check(cell.alive(), "the simulated cell exited")


# The node records to the directory given (argument 1): `waam replay` re-runs the revisions.
waamtest.run(test, "node", "--dry-run", "--params", "tests/ros/closed_loop_execute.params.yaml",
             "--record", sys.argv[1], "--ros-args", "-r", "__ns:=/cellS")
