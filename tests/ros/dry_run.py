"""`waam publish PART --dry-run`: the simulated controller publishes /joint_states that
follow the published trajectory, and ~/arc_on goes on and off once per fragment; then the
command exits 0."""

from sensor_msgs.msg import JointState
from std_msgs.msg import Bool
from trajectory_msgs.msg import JointTrajectory

import waamtest
from waamtest import check

NS = "/waam_planner"


def test(peer, waam):
    peer.listen("/joint_states", JointState, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/arc_on", Bool, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/plan/joint_trajectory", JointTrajectory)
    peer.spin_until("waam publish --dry-run to finish", lambda: not waam.alive(), 120)
    peer.spin_for(1.0)
    check(waam.proc.returncode == 0, f"waam publish --dry-run exited {waam.proc.returncode}")
    traj = peer.received[NS + "/plan/joint_trajectory"]
    check(traj, "no trajectory received")
    traj = traj[-1]
    states = peer.received["/joint_states"]
    check(len(states) >= 10, f"only {len(states)} joint states")
    check(all(list(s.name) == list(traj.joint_names) for s in states), "joint names differ")
    positions = [tuple(s.position) for s in states]
    check(len(set(positions)) >= 5, "the simulated robot did not move")
    # Following the trajectory: it ends on the trajectory's last point, and every state lies
    # within the trajectory's joint ranges.
    last = traj.points[-1].positions
    check(max(abs(a - b) for a, b in zip(positions[-1], last)) < 1e-6,
          f"final joint state {positions[-1]} is not the trajectory's end {list(last)}")
    for j in range(len(last)):
        lo = min(p.positions[j] for p in traj.points) - 1e-9
        hi = max(p.positions[j] for p in traj.points) + 1e-9
        check(all(lo <= p[j] <= hi for p in positions), f"joint {j} leaves the trajectory")
    arcs = [m.data for m in peer.received[NS + "/arc_on"]]
    check(arcs and arcs == [i % 2 == 0 for i in range(len(arcs))] and len(arcs) % 2 == 0,
          f"arc sequence {arcs}")


waamtest.run(test, "publish", "config/parts/s1-wall.yaml", "--dry-run",
             "--params", "tests/ros/fast.params.yaml", "--wait-for-subscriber", "30",
             "--linger", "1")
