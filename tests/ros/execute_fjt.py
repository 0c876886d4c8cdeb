"""~/execute against a test FollowJointTrajectory controller in rclpy.

waam node runs with tests/ros/execute.params.yaml: execution on /test_controller, plans run
only on a ~/execute goal, at most 5 points per goal, MotoROS2 joint names and tolerances.
This script serves that controller (control_msgs built from tests/ros/interfaces by
scripts/build-interfaces.sh), plans s1-wall through ~/plan, and executes it through
~/execute. It checks:
- every goal carries the mapped joint names and the tolerances of the parameters;
- the goals together are the published trajectory, in order, each point once;
- no goal boundary (where the robot stops between goals) falls inside an arc-on stretch,
  the arc-on stretches taken from the published weld plan's toolpath (ARC_ON to ARC_OFF
  times); a weld longer than the cap therefore goes as one goal, while arc-off moves are cut
  at the cap;
- the feedback names every goal chunk in order with its points and arc state; ~/arc_on
  goes on and off once per weld path; the result says EXECUTED for the planned job;
- cancelling an ~/execute goal cancels the controller's goal and leaves the arc off;
- an unknown plan is refused with the reason (NO_PLAN).
"""

import os
import threading
import time

import rclpy
from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory
from rclpy.action import ActionClient, ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from std_msgs.msg import Bool
from trajectory_msgs.msg import JointTrajectory
from waam_interfaces.action import ExecutePlan, PlanPart
from waam_interfaces.msg import WeldPlan, WeldPoint

import waamtest
from waamtest import REPO, check

CAP = 5
MAPPED = [f"group_1/joint_{j}" for j in range(1, 7)]
NODE = "/waam_planner"


def seconds(duration):
    return duration.sec + duration.nanosec * 1e-9


class TestController:
    """A FollowJointTrajectory server that checks and records each goal; a goal takes `hold`
    seconds unless cancelled."""

    def __init__(self, node, events, lock):
        self.goals = []
        self.problems = []
        self.cancels = 0
        self.hold = 0.0
        self.events = events
        self.lock = lock
        ActionServer(
            node,
            FollowJointTrajectory,
            "/test_controller/follow_joint_trajectory",
            execute_callback=self.execute,
            goal_callback=lambda _goal: GoalResponse.ACCEPT,
            cancel_callback=self.cancel,
            callback_group=ReentrantCallbackGroup(),
        )

    def execute(self, handle):
        goal = handle.request
        index = len(self.goals)
        result = FollowJointTrajectory.Result()
        problems = []
        if list(goal.trajectory.joint_names) != MAPPED:
            problems.append(f"goal {index}: joint names {list(goal.trajectory.joint_names)}")
            result.error_code = FollowJointTrajectory.Result.INVALID_JOINTS
        for what, tolerances, value in (
            ("path", goal.path_tolerance, 0.1),
            ("goal", goal.goal_tolerance, 0.01),
        ):
            names = [t.name for t in tolerances]
            if names != MAPPED or any(t.position != value for t in tolerances):
                problems.append(
                    f"goal {index}: {what} tolerances "
                    f"{[(t.name, t.position) for t in tolerances]}, expected {value} per joint"
                )
        if abs(seconds(goal.goal_time_tolerance) - 0.5) > 1e-9:
            problems.append(f"goal {index}: goal time tolerance {goal.goal_time_tolerance}")
        with self.lock:
            self.goals.append(goal.trajectory)
            self.problems += problems
            self.events.append(("goal", index))
        deadline = time.monotonic() + self.hold
        while time.monotonic() < deadline:
            if handle.is_cancel_requested:
                handle.canceled()
                result.error_string = "cancelled"
                return result
            time.sleep(0.01)
        if result.error_code == 0:
            handle.succeed()
        else:
            handle.abort()
        return result

    def cancel(self, _handle):
        with self.lock:
            self.cancels += 1
        return CancelResponse.ACCEPT


def wait(what, condition, timeout, discovery=False):
    """Waits for `condition`; a timeout is a DiscoveryTimeout when `discovery` is set."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.02)
    if not condition():
        failure = waamtest.DiscoveryTimeout if discovery else waamtest.Failure
        raise failure(f"timed out after {timeout} s waiting for {what}")


def result_of(client, goal, timeout, feedback=None):
    """Sends `goal`, waits for its result; returns (goal handle, status, result)."""
    sent = client.send_goal_async(goal, feedback_callback=feedback)
    # No answer at all: the server's answer to a client it had not yet found is lost
    # (DDS discovery; see waamtest.plan_then_execute).
    wait("the goal to be accepted", sent.done, 30, discovery=True)
    handle = sent.result()
    check(handle.accepted, "the goal was rejected")
    got = handle.get_result_async()
    wait("the goal's result", got.done, timeout)
    return handle, got.result().status, got.result().result


def test(waam):
    rclpy.init()
    node = Node("waam_test_controller")
    lock = threading.Lock()
    events = []
    controller = TestController(node, events, lock)
    received = {"trajectory": [], "weld_plan": []}
    def on_arc(msg):
        with lock:
            events.append(("arc", msg.data))

    node.create_subscription(Bool, NODE + "/arc_on", on_arc, waamtest.INPUT_QOS)
    node.create_subscription(
        JointTrajectory,
        NODE + "/plan/joint_trajectory",
        lambda m: received["trajectory"].append(m),
        waamtest.LATCHED_QOS,
    )
    node.create_subscription(
        WeldPlan,
        NODE + "/plan/weld_plan",
        lambda m: received["weld_plan"].append(m),
        waamtest.LATCHED_QOS,
    )
    plan = ActionClient(node, PlanPart, NODE + "/plan")
    execute = ActionClient(node, ExecutePlan, NODE + "/execute")
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    spinner = threading.Thread(target=executor.spin, daemon=True)
    spinner.start()
    try:
        for client, name, timeout in ((plan, "~/plan", 60), (execute, "~/execute", 30)):
            if not client.wait_for_server(timeout_sec=timeout):
                raise waamtest.DiscoveryTimeout(f"no {name} action server after {timeout} s")

        # An unknown plan is refused with the reason.
        _, status, r = result_of(execute, ExecutePlan.Goal(job=4242), 30)
        check(
            status == GoalStatus.STATUS_ABORTED and r.outcome == ExecutePlan.Result.NO_PLAN,
            f"~/execute of an unknown plan: status {status}, {r}",
        )
        check("4242" in r.message, f"the reason does not name the plan: {r.message!r}")

        # Plan s1-wall; nothing runs before ~/execute (execution.auto_execute is false).
        with open(os.path.join(REPO, "config/parts/s1-wall.yaml"), encoding="utf-8") as f:
            part = f.read()
        _, status, planned = result_of(
            plan, PlanPart.Goal(part_document=part, first_feasible=True, timeout_s=60.0), 120
        )
        check(
            status == GoalStatus.STATUS_SUCCEEDED and planned.outcome == PlanPart.Result.PLANNED,
            f"~/plan: status {status}, outcome {planned.outcome}, {planned.reason}",
        )
        check(planned.job > 0, f"the ~/plan result names no job: {planned.job}")
        wait("the trajectory and weld plan", lambda: received["trajectory"] and received["weld_plan"], 30)
        time.sleep(0.5)
        check(not controller.goals, f"{len(controller.goals)} goals ran before ~/execute")

        # Execute it.
        feedback = []
        _, status, r = result_of(
            execute,
            ExecutePlan.Goal(job=planned.job),
            180,
            feedback=lambda m: feedback.append(m.feedback),
        )
        check(
            status == GoalStatus.STATUS_SUCCEEDED and r.outcome == ExecutePlan.Result.EXECUTED,
            f"~/execute: status {status}, {r}",
        )
        check(r.job == planned.job, f"executed job {r.job}, planned {planned.job}")
        time.sleep(1.0)  # the last arc-off message
        with lock:
            problems = list(controller.problems)
            goals = list(controller.goals)
            arcs = [on for kind, on in events if kind == "arc"]
        check(not problems, "goal problems:\n" + "\n".join(problems))

        trajectory = received["trajectory"][-1]
        weld_plan = received["weld_plan"][-1]
        check(len(goals) > 1, f"expected several goals, got {len(goals)}")
        sent = [list(p.positions) for g in goals for p in g.points]
        whole = [list(p.positions) for p in trajectory.points]
        check(sent == whole, f"the goals ({len(sent)} points) are not the trajectory "
              f"({len(whole)} points), in order, once")

        # Arc-on stretches of the published plan: from each weld path's ARC_ON point to its
        # ARC_OFF point (times from the start, as the trajectory's).
        welds = []
        for fragment in range(len(weld_plan.fragments)):
            times = {
                p.kind: seconds(p.time_from_start)
                for p in weld_plan.points
                if p.fragment == fragment and p.kind in (WeldPoint.ARC_ON, WeldPoint.ARC_OFF)
            }
            check(len(times) == 2, f"weld path {fragment}: no ARC_ON/ARC_OFF pair")
            welds.append((times[WeldPoint.ARC_ON], times[WeldPoint.ARC_OFF]))
        ends, end = [], -1
        for g in goals:
            end += len(g.points)
            ends.append(end)
        boundaries = ends[:-1]  # where the robot stops between two goals
        eps = 1e-6
        for p in boundaries:
            t = seconds(trajectory.points[p].time_from_start)
            for on, off in welds:
                check(not on + eps < t < off - eps, f"a goal ends at trajectory point {p} "
                      f"(t = {t:.3f} s), inside the weld from {on:.3f} s to {off:.3f} s")
        longest = max(len(g.points) for g in goals)
        check(longest > CAP, f"no weld went whole as one goal (longest goal {longest} points)")

        # Feedback: each chunk once, in order, with its points and arc state.
        chunks = [(f.chunk, f.chunks) for f in feedback]
        check(chunks == [(i + 1, len(goals)) for i in range(len(goals))],
              f"feedback chunks {chunks}, {len(goals)} goals")
        start = 0
        for f, g, last in zip(feedback, goals, ends):
            check((f.first_point, f.last_point) == (start, last),
                  f"chunk {f.chunk}: points {f.first_point}..{f.last_point}, the goal had "
                  f"{start}..{last}")
            t_mid = seconds(trajectory.points[last].time_from_start) - 1e-3
            welding = any(on - eps <= t_mid <= off + eps for on, off in welds)
            check(f.arc_on == welding, f"chunk {f.chunk}: arc_on {f.arc_on}, the weld plan says "
                  f"{welding}")
            check(f.arc_on == (f.weld_path > 0), f"chunk {f.chunk}: {f}")
            start = last + 1
        arc_off = [len(g.points) for f, g in zip(feedback, goals) if not f.arc_on]
        check(max(arc_off) <= CAP and arc_off.count(CAP) > 0,
              f"arc-off goals of {arc_off} points: expected them cut at the cap of {CAP}")
        check(sum(f.arc_on for f in feedback) == len(welds),
              f"{sum(f.arc_on for f in feedback)} welding chunks for {len(welds)} weld paths")
        check(arcs == [True, False] * len(welds), f"~/arc_on: {arcs}")

        # Cancel an execution: the controller's goal is cancelled, the arc goes off.
        controller.hold = 3.0
        with lock:
            events.clear()
            before = len(controller.goals)
        sent = execute.send_goal_async(ExecutePlan.Goal(job=0))
        wait("the second ~/execute goal to be accepted", sent.done, 30)
        handle = sent.result()
        wait("the controller's first goal", lambda: len(controller.goals) > before, 30)
        cancel_at = time.monotonic()
        handle.cancel_goal_async()
        got = handle.get_result_async()
        wait("the cancelled goal's result", got.done, 10)
        took = time.monotonic() - cancel_at
        status, r = got.result().status, got.result().result
        check(
            status == GoalStatus.STATUS_CANCELED and r.outcome == ExecutePlan.Result.CANCELLED,
            f"cancelled ~/execute: status {status}, {r}",
        )
        check(took < 2.0, f"the cancel took {took:.2f} s")
        wait("the controller to see the cancel", lambda: controller.cancels >= 1, 5)
        time.sleep(0.5)
        with lock:
            arcs = [on for kind, on in events if kind == "arc"]
        check(not arcs or arcs[-1] is False, f"the arc is left on after the cancel: {arcs}")
        print(
            f"executed job {planned.job}: {len(goals)} goals (longest {longest} points, cap "
            f"{CAP}), {len(welds)} weld paths, {len(boundaries)} boundaries all outside welds; "
            f"cancel answered in {took:.2f} s"
        )
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.shutdown()


def main():
    waam = waamtest.WaamProcess("node", "--params", "tests/ros/execute.params.yaml")
    try:
        test(waam)
    except waamtest.Failure as e:
        print(f"FAIL{' ' if isinstance(e, waamtest.DiscoveryTimeout) else ': '}{e}")
        print(f"--- log of {' '.join(waam.args)} ---\n{waam.output()}")
        raise SystemExit(1)
    finally:
        waam.stop()
    print(f"--- log of {' '.join(waam.args)} ---\n{waam.output()}")
    print("PASS")


if __name__ == "__main__":
    main()
