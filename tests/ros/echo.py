"""Interop smoke test: rclpy publishes a part document, waam_planner answers on ~/status."""

from std_msgs.msg import String

import waamtest
from waamtest import check


def test(peer, waam):
    peer.listen("/waam_planner/status", String, qos=waamtest.INPUT_QOS)
    part = peer.publisher("/waam_planner/part", String)
    peer.wait_for_subscriber(part)
    part.publish(String(data="x" * 1000))
    peer.spin_until("a status", lambda: peer.received["/waam_planner/status"], 30)
    check(waam.alive(), "waam node exited")


waamtest.run(test, "node")
