"""Reads a recorded session with the Python MCAP and rosbag2 readers and checks it.

Usage: check_session.py BAG_DIR EXPECTED_JSON

EXPECTED_JSON maps each topic to {"type": ..., "count": ...}: what the recording process says
it published. Every message is decoded twice, with mcap-ros2-support (from the schemas in the
file) and with rosbags (opening the directory as a rosbag2 bag with MCAP storage); counts and
types must match, and each type's content must make sense. Prints a JSON summary; exits 1 with
the reasons on any failure.
"""

import json
import math
import re
import sys
from collections import Counter
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

HASH = re.compile(r"^RIHS01_[0-9a-f]{64}$")
problems = []


def check(ok, what):
    if not ok:
        problems.append(what)


def check_content(type_name, msg, topic):
    """Type-specific sanity of a decoded message (attribute access works for both readers)."""
    where = f"{topic} ({type_name})"
    if type_name == "std_msgs/msg/String" and topic.endswith("/robot_description"):
        check("<robot" in msg.data and "<link" in msg.data, f"{where}: not a URDF")
    elif type_name == "std_msgs/msg/String":
        check("name:" in msg.data, f"{where}: part text has no name")
    elif type_name == "tf2_msgs/msg/TFMessage":
        check(len(msg.transforms) > 0, f"{where}: no transforms")
        for t in msg.transforms:
            check(t.header.frame_id and t.child_frame_id, f"{where}: a transform without frames")
            q = t.transform.rotation
            check(abs(q.x**2 + q.y**2 + q.z**2 + q.w**2 - 1) < 1e-9, f"{where}: not a unit quaternion")
    elif type_name == "shape_msgs/msg/Mesh":
        n = len(msg.vertices)
        check(n > 0 and len(msg.triangles) > 0, f"{where}: empty mesh")
        for t in msg.triangles:
            check(all(0 <= int(i) < n for i in t.vertex_indices), f"{where}: bad index")
    elif type_name == "trajectory_msgs/msg/JointTrajectory":
        names = list(msg.joint_names)
        check(len(names) == 6, f"{where}: {len(names)} joints")
        times = [p.time_from_start.sec + p.time_from_start.nanosec * 1e-9 for p in msg.points]
        check(all(a <= b for a, b in zip(times, times[1:])), f"{where}: times not monotone")
        for p in msg.points:
            check(len(p.positions) == len(names), f"{where}: positions do not match joints")
    elif type_name == "geometry_msgs/msg/PoseArray":
        check(len(msg.poses) > 0, f"{where}: no poses")
        for p in msg.poses:
            q = p.orientation
            check(abs(q.x**2 + q.y**2 + q.z**2 + q.w**2 - 1) < 1e-9, f"{where}: not a unit quaternion")
    elif type_name == "nav_msgs/msg/Path":
        check(len(msg.poses) > 0, f"{where}: empty path")
    elif type_name == "visualization_msgs/msg/MarkerArray":
        texts = [m.text for m in msg.markers]
        check(any(t.startswith("arc on") for t in texts) and any(t.startswith("arc off") for t in texts),
              f"{where}: no arc on/off labels")
    elif type_name == "waam_interfaces/msg/WeldPlan":
        blocks = [(b.x, b.y, b.z) for f in msg.fragments for b in f.blocks]
        check(len(blocks) == len(set(blocks)) > 0, f"{where}: blocks repeated or none")
        check(len(msg.points) > 0, f"{where}: no toolpath")
        welding = [p for p in msg.points if p.arc_on]
        check(welding and welding[0].kind == 1, f"{where}: the arc does not start with ARC_ON")
        kinds = [int(p.kind) for p in msg.points]
        check(kinds.count(1) == kinds.count(3) > 0, f"{where}: ARC_ON and ARC_OFF do not pair")
    elif type_name == "diagnostic_msgs/msg/DiagnosticArray":
        for s in msg.status:
            check(int(s.level) in (0, 1, 2, 3), f"{where}: level {s.level}")
    elif type_name == "std_msgs/msg/Bool":
        check(msg.data in (True, False), f"{where}: not a bool")
    elif type_name == "sensor_msgs/msg/JointState":
        check(len(msg.name) == len(msg.position), f"{where}: names and positions differ")
    elif type_name == "rcl_interfaces/msg/Log":
        check(int(msg.level) in (10, 20, 30, 40, 50), f"{where}: level {msg.level}")
    elif type_name == "waam_interfaces/msg/PlanCandidate":
        check(int(msg.verdict) in range(6), f"{where}: verdict {msg.verdict}")
        check(msg.index >= 1, f"{where}: index {msg.index}")
    elif type_name == "sensor_msgs/msg/PointCloud2":
        names = [f.name for f in msg.fields]
        check(names == ["x", "y", "z", "temperature"], f"{where}: fields {names}")
        data = bytes(msg.data)
        check(len(data) == msg.width * msg.height * msg.point_step, f"{where}: data size")
        import struct
        for k in range(msg.width):
            x, y, z, t = struct.unpack_from("<4f", data, k * msg.point_step)
            check(math.isfinite(t) and t > 0, f"{where}: temperature {t}")
    else:
        problems.append(f"{where}: type not expected in a session")


def read_with_mcap(mcap_path, expected):
    counts = Counter()
    with open(mcap_path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        header = reader.get_header()
        check(header.profile == "ros2", f"profile {header.profile!r}")
        summary = reader.get_summary()
        check(summary is not None, "no summary section")
        stats = summary.statistics
        check(stats.message_count == sum(e["count"] for e in expected.values()),
              f"statistics say {stats.message_count} messages")
        check(len(summary.chunk_indexes) >= 1, "no chunk index")
        for ci in summary.chunk_indexes:
            check(ci.compression == "zstd", f"chunk compression {ci.compression!r}")
            check(len(ci.message_index_offsets) > 0 and ci.message_index_length > 0,
                  "a chunk without message indexes")
        for schema in summary.schemas.values():
            check(schema.encoding == "ros2msg", f"schema {schema.name}: {schema.encoding}")
        for channel in summary.channels.values():
            check(channel.message_encoding == "cdr", f"{channel.topic}: {channel.message_encoding}")
            check("offered_qos_profiles" in channel.metadata, f"{channel.topic}: no QoS")
            check(HASH.match(channel.metadata.get("topic_type_hash", "")) is not None,
                  f"{channel.topic}: type hash {channel.metadata.get('topic_type_hash')!r}")
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            counts[channel.topic] += 1
            check(schema.name == expected.get(channel.topic, {}).get("type"),
                  f"{channel.topic}: schema {schema.name}")
            check(message.data[:4] == b"\x00\x01\x00\x00", f"{channel.topic}: not CDR_LE")
            check_content(schema.name, decoded, channel.topic)
    with open(mcap_path, "rb") as f:
        metadata = [m for m in make_reader(f).iter_metadata() if m.name == "rosbag2"]
        check(metadata and metadata[-1].metadata.get("ROS_DISTRO") == "jazzy", "no rosbag2 record")
    return counts


def read_with_rosbags(bag_dir, expected):
    counts = Counter()
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag_dir) as reader:
        check(reader.ros_distro == "jazzy", f"ros_distro {reader.ros_distro}")
        check(reader.message_count == sum(e["count"] for e in expected.values()),
              f"rosbags: {reader.message_count} messages")
        ours = {}
        for c in reader.connections:
            check(c.msgtype == expected.get(c.topic, {}).get("type"), f"rosbags: {c.topic} is {c.msgtype}")
            check(c.msgcount == expected.get(c.topic, {}).get("count"), f"rosbags: {c.topic} count {c.msgcount}")
            check(len(c.ext.offered_qos_profiles) == 1, f"rosbags: {c.topic} QoS")
            if c.msgtype not in store.types:
                ours.update(get_types_from_msg(c.msgdef.data, c.msgtype))
        store.register(ours)
        for connection, _, raw in reader.messages():
            msg = store.deserialize_cdr(raw, connection.msgtype)
            counts[connection.topic] += 1
            check_content(connection.msgtype, msg, connection.topic)
    return counts


def main():
    bag_dir = Path(sys.argv[1])
    expected = json.loads(Path(sys.argv[2]).read_text())
    mcap_files = sorted(bag_dir.glob("*.mcap"))
    check(len(mcap_files) == 1, f"{len(mcap_files)} mcap files")
    by_mcap = read_with_mcap(mcap_files[0], expected)
    by_rosbags = read_with_rosbags(bag_dir, expected)
    for topic, e in expected.items():
        check(by_mcap[topic] == e["count"], f"mcap: {topic} has {by_mcap[topic]}, expected {e['count']}")
        check(by_rosbags[topic] == e["count"], f"rosbags: {topic} has {by_rosbags[topic]}")
    check(set(by_mcap) == set(expected), f"mcap topics {sorted(by_mcap)}")
    print(json.dumps({"mcap": by_mcap, "rosbags": by_rosbags, "problems": problems}))
    if problems:
        print("\n".join(problems[:50]), file=sys.stderr)
        sys.exit(1)


main()
