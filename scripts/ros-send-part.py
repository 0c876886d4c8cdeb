#!/usr/bin/env python3
"""Sends a part document to a running waam_planner and prints its status until the part is
planned (exit 0) or fails (exit 1). Needs rclpy: run it with .venv-ros/bin/python (from
scripts/ros-venv.sh) or in a sourced ROS 2 Jazzy environment.

Usage: ros-send-part.py PART.yaml [--node /waam_planner] [--timeout SECONDS]
"""

import argparse
import sys
import time

import rclpy
from diagnostic_msgs.msg import DiagnosticArray
from rclpy.qos import QoSProfile, ReliabilityPolicy
from std_msgs.msg import String

parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
parser.add_argument("part")
parser.add_argument("--node", default="/waam_planner")
parser.add_argument("--timeout", type=float, default=120.0)
args = parser.parse_args()

with open(args.part, encoding="utf-8") as f:
    document = f.read()

rclpy.init()
node = rclpy.create_node("waam_send_part")
qos = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE)
state = {"sent": False, "before": 0, "job": None, "outcome": None}


def on_status(msg):
    for s in msg.status:
        values = {kv.key: kv.value for kv in s.values}
        job = int(values.get("job", 0) or 0)
        if not state["sent"]:
            # Statuses of earlier parts (a latched status may replay them): remember the
            # highest job number, so that ours is the next one.
            state["before"] = max(state["before"], job)
            continue
        if job <= state["before"]:
            continue
        print(f"[{values.get('state', '?')}] {s.message}", flush=True)
        if state["job"] is None and values.get("state") == "received":
            state["job"] = job
        if job == state["job"] and values.get("state") in ("planned", "error"):
            state["outcome"] = values["state"]


node.create_subscription(DiagnosticArray, args.node + "/status", on_status, qos)
pub = node.create_publisher(String, args.node + "/part", qos)
deadline = time.monotonic() + args.timeout
while pub.get_subscription_count() == 0 and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
if pub.get_subscription_count() == 0:
    sys.exit(f"no subscriber on {args.node}/part: is waam node running on this domain?")
settle = time.monotonic() + 1.0  # let the status subscription match and drain old news
while time.monotonic() < settle:
    rclpy.spin_once(node, timeout_sec=0.05)
state["sent"] = True
pub.publish(String(data=document))
while state["outcome"] is None and time.monotonic() < deadline:
    rclpy.spin_once(node, timeout_sec=0.1)
sys.exit(0 if state["outcome"] == "planned" else 1)
