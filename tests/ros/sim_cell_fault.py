"""An arc fault from the simulated cell's welder (#31): `waam sim-cell --node` with
tests/data/truth-cut-short.yaml cuts the first weld path short after 12 of its 24 deposits and
publishes the fault on the planner's ~/arc_fault; `waam node` (/cellF/waam_planner, a dry run
at 20 times real time, closed loop on) stops that weld goal, re-plans the rest from what was
welded and completes the part. rclpy only sends the part and the ~/execute goal.

It checks: the execution succeeds; a `replanned` status with reason `fault` says weld path 1
was cut short after 12 deposits; the re-plan was published and welds every block once; the
arc-fault sensor on /diagnostics saw the fault.
"""

import sys

from diagnostic_msgs.msg import DiagnosticArray
from waam_interfaces.msg import WeldPlan

import waamtest
from waamtest import check

NS = "/cellF/waam_planner"


def test(peer, waam):
    waamtest.beside_the_simulated_cell(peer, run, "tests/data/twin-walls.yaml",
                                       "--truth", "tests/data/truth-cut-short.yaml", "--node",
                                       "--time-scale", "20", "--ros-args", "-r", "__ns:=/cellF")


def run(peer, cell):
    peer.listen("/diagnostics", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/plan/weld_plan", WeldPlan)
    waamtest.execute_beside_the_simulated_cell(peer, NS, cell)

    replanned = waamtest.statuses(peer, NS + "/status", "replanned")
    for s in replanned:
        print(f"replanned: {s}")
    faults = [s for s in replanned if s.get("reason") == "fault"]
    check(faults, f"no re-plan after the arc fault: {replanned}")
    check(faults[0].get("cut_short_weld_path") == "1"
          and faults[0].get("cut_short_deposits") == "12",
          f"the fault's status: {faults[0]}")
    # The plan welded last: the cut weld path of 12 deposits first, every block once.
    plans = peer.received[NS + "/plan/weld_plan"]
    check(plans, "no weld plan received")
    last = plans[-1]
    check(len(last.fragments[0].blocks) == 12, f"first weld path: {last.fragments[0]}")
    blocks = [(b.x, b.y, b.z) for f in last.fragments for b in f.blocks]
    check(len(blocks) == 48 and len(set(blocks)) == 48, f"blocks welded: {blocks}")
    seen = [s.message for a in peer.received["/diagnostics"] for s in a.status
            if s.name == "cellF/waam_planner: arc fault sensor"]
    check(any("the arc went out" in m for m in seen), f"arc fault sensor: {set(seen)}")


# The node records to the directory given (argument 1): `waam replay` re-runs its decisions.
waamtest.run(test, "node", "--dry-run", "--params", "tests/ros/closed_loop_execute.params.yaml",
             "--record", sys.argv[1], "--ros-args", "-r", "__ns:=/cellF")
