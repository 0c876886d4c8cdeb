"""The closed loop's sensors (#31): a namespaced node takes a layer scan, a pyrometer and a
thermal camera.

waam node runs as /cellX/waam_planner (`-r __ns:=/cellX`), recording into the directory
given as the one argument (tests/cli/ros_node.rs checks the recording). rclpy plans s1-wall
(24 x 6 x 7.5 mm) on ~/part, then publishes on ~/scan (sensor_msgs/PointCloud2, metres, frame
`part`), ~/temperature (sensor_msgs/Temperature) and ~/thermal_image (sensor_msgs/PointCloud2
with a `temperature` field, °C) with the sensor-data QoS real drivers use
(best effort): good data, then each kind of bad data followed by good data again. Each bad
message must turn its sensor's component on /diagnostics to WARN naming the topic and the
reason; the next good one must turn it back to OK. A scan in a frame the node only knows
from /tf_static (a scanner on the fixture, 0.1 m above the part frame) is placed on the part.
The welder's arc faults on ~/arc_fault (std_msgs/Header, reliable): a late one is a WARN, a
good one with no weld path running is OK and stops nothing. The node must never stop.
"""

import math
import struct
import sys
import time

from diagnostic_msgs.msg import DiagnosticArray
from geometry_msgs.msg import TransformStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import PointCloud2, PointField, Temperature
from std_msgs.msg import Header, String
from tf2_msgs.msg import TFMessage  # the tests' copy (tests/ros/interfaces)

import waamtest
from waamtest import REPO, check

NS = "/cellX/waam_planner"
SCAN, TEMPERATURE = NS + "/scan", NS + "/temperature"
IMAGE, ARC_FAULT = NS + "/thermal_image", NS + "/arc_fault"


def stamp(peer, offset_s=0.0):
    t = peer.node.get_clock().now().nanoseconds + int(offset_s * 1e9)
    from builtin_interfaces.msg import Time

    return Time(sec=t // 10**9, nanosec=t % 10**9)


def cloud(peer, points, frame="part", offset_s=0.0, fields=("x", "y", "z")):
    """FLOAT32 points (metres) as a laser line scanner driver sends them (with a fourth
    field, a thermal camera's image mapped onto the part)."""
    msg = PointCloud2()
    msg.header.stamp = stamp(peer, offset_s)
    msg.header.frame_id = frame
    msg.height, msg.width = 1, len(points)
    msg.fields = [PointField(name=n, offset=4 * i, datatype=PointField.FLOAT32, count=1)
                  for i, n in enumerate(fields)]
    n = len(fields)
    msg.point_step, msg.row_step = 4 * n, 4 * n * len(points)
    msg.data = b"".join(struct.pack(f"<{n}f", *p) for p in points)
    msg.is_dense = True
    return msg


THERMAL = ("x", "y", "z", "temperature")


def image(peer, celsius, fields=THERMAL):
    """A thermal image of the wall's top: three points with their temperatures."""
    return cloud(peer, [(*p, c) for p, c in zip(TOP[:3], celsius)], fields=fields)


def reading(peer, celsius, offset_s=0.0):
    msg = Temperature(temperature=celsius, variance=0.0)
    msg.header.stamp = stamp(peer, offset_s)
    msg.header.frame_id = "pyrometer"
    return msg


# The top of s1-wall's third layer (7.5 mm), along its centre line, and one point on the
# plate beside it (dropped, not an error).
TOP = [(0.003 + 0.006 * i, 0.003, 0.0075) for i in range(4)] + [(0.040, 0.003, 0.0)]


def sensor_status(array, kind):
    for s in array.status:
        if s.name == f"cellX/waam_planner: {kind} sensor":
            return s
    return None


def expect(peer, publish, kind, level, words, what):
    """Publishes (again every half second: best effort may drop one) until /diagnostics
    reports the `kind` sensor at `level` with every one of `words` in its message."""
    seen = len(peer.received["/diagnostics"])
    last = [None]

    def reported():
        for array in peer.received["/diagnostics"][seen:]:
            s = sensor_status(array, kind)
            if s is not None:
                last[0] = (waamtest.level(s), s.message)
                if waamtest.level(s) == level and all(w in s.message for w in words):
                    return True
        return False

    deadline = time.monotonic() + 20
    while time.monotonic() < deadline and not reported():
        publish()
        peer.spin_for(0.5)
    check(reported(), f"{what}: /diagnostics never said level {level} with {words}; last: {last[0]}")
    print(f"{what}: {last[0]}")


def test(peer, waam):
    peer.listen("/diagnostics", DiagnosticArray, qos=waamtest.INPUT_QOS)
    peer.listen(NS + "/status", DiagnosticArray, qos=waamtest.INPUT_QOS)
    part = peer.publisher(NS + "/part", String)
    scan = peer.publisher(SCAN, PointCloud2, qos=qos_profile_sensor_data)
    temperature = peer.publisher(TEMPERATURE, Temperature, qos=qos_profile_sensor_data)
    camera = peer.publisher(IMAGE, PointCloud2, qos=qos_profile_sensor_data)
    arc_fault = peer.publisher(ARC_FAULT, Header)  # reliable, as the node asks
    for p in (part, scan, temperature, camera, arc_fault):
        peer.wait_for_subscriber(p)

    # The sensors are listed before any data came.
    peer.spin_until(
        "the sensors on /diagnostics",
        lambda: any(sensor_status(a, "scan") and sensor_status(a, "temperature")
                    and sensor_status(a, "thermal camera") and sensor_status(a, "arc fault")
                    for a in peer.received["/diagnostics"]),
        30,
        discovery=True,
    )

    # A temperature needs no part; a scan does.
    ok, warn = 0, 1  # DiagnosticStatus.OK, .WARN (rclpy gives those as bytes)
    good_t = lambda: temperature.publish(reading(peer, 650.0))  # noqa: E731
    expect(peer, good_t, "temperature", ok, [TEMPERATURE, "650.0 °C"], "good temperature")
    expect(peer, lambda: scan.publish(cloud(peer, TOP)), "scan", warn,
           [SCAN, "no part planned yet"], "scan before any part")

    with open(f"{REPO}/config/parts/s1-wall.yaml") as f:
        part.publish(String(data=f.read()))
    peer.spin_until(
        "s1-wall planned",
        lambda: any(kv.key == "state" and kv.value == "planned"
                    for a in peer.received[NS + "/status"] for s in a.status for kv in s.values),
        120,
    )
    good_s = lambda: scan.publish(cloud(peer, TOP))  # noqa: E731
    expect(peer, good_s, "scan", ok, [SCAN, "4 points on the part (1 off it dropped)", "7.50 mm"],
           "good scan")

    bad_temperatures = [
        ("NaN", lambda: reading(peer, math.nan), ["not a number"]),
        ("5000 °C", lambda: reading(peer, 5000.0), ["5000", "plausible"]),
        ("10 s late", lambda: reading(peer, 650.0, offset_s=-10.0), ["late", "max_age_s"]),
    ]
    for what, msg, words in bad_temperatures:
        expect(peer, lambda: temperature.publish(msg()), "temperature", warn, [TEMPERATURE, *words],
               f"temperature {what}")
        expect(peer, good_t, "temperature", ok, [TEMPERATURE, "650.0 °C"], f"good after {what}")

    nan_top = [TOP[0], (0.009, math.nan, 0.0075)]
    bad_scans = [
        ("a NaN point", lambda: cloud(peer, nan_top), ["point 1 is not finite"]),
        ("no z field", lambda: cloud(peer, TOP, fields=("x", "y", "w")),
         ["no FLOAT32 or FLOAT64 field 'z'"]),
        ("an unknown frame", lambda: cloud(peer, TOP, frame="scanner_link"),
         ["'scanner_link'", "base link"]),
        ("millimetres as metres", lambda: cloud(peer, [(3.0, 3.0, 7.5)]), ["off the part"]),
        ("5 s late", lambda: cloud(peer, TOP, offset_s=-5.0), ["late"]),
    ]
    for what, msg, words in bad_scans:
        expect(peer, lambda: scan.publish(msg()), "scan", warn, [SCAN, *words], f"scan with {what}")
        expect(peer, good_s, "scan", ok, [SCAN, "4 points on the part"], f"good after {what}")

    # A thermal camera's image: good, then bad ways, each followed by a good one.
    good_i = lambda: camera.publish(image(peer, [900.0, 850.0, math.nan]))  # noqa: E731
    good_words = [IMAGE, "2 points read on the part", "1 unread", "900.0 °C"]
    expect(peer, good_i, "thermal camera", ok, good_words, "good thermal image")
    bad_images = [
        ("Kelvin", lambda: image(peer, [1173.0, 1123.0, 3273.0]), ["point 2", "3273", "°C"]),
        ("no temperature field", lambda: image(peer, [900.0] * 3, fields=("x", "y", "z", "t")),
         ["no FLOAT32 or FLOAT64 field 'temperature'"]),
        ("nothing read", lambda: image(peer, [math.nan] * 3), ["no temperature on the part"]),
    ]
    for what, msg, words in bad_images:
        expect(peer, lambda: camera.publish(msg()), "thermal camera", warn, [IMAGE, *words],
               f"thermal image with {what}")
        expect(peer, good_i, "thermal camera", ok, good_words, f"good after {what}")

    # A scanner on the fixture, known from /tf_static only (transient local, as tf2's static
    # broadcaster publishes): its scan, 0.1 m below it, lands on the wall's top.
    below = [(x, y, z - 0.1) for x, y, z in TOP]
    fixture = lambda: scan.publish(cloud(peer, below, frame="fixture_scanner"))  # noqa: E731
    expect(peer, fixture, "scan", warn, [SCAN, "'fixture_scanner'", "/tf_static"],
           "scan in a frame nobody published yet")
    mount = TransformStamped(child_frame_id="fixture_scanner")
    mount.header.stamp = stamp(peer)
    mount.header.frame_id = "part"
    mount.transform.translation.z = 0.1
    latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    peer.node.create_publisher(TFMessage, "/tf_static", latched).publish(
        TFMessage(transforms=[mount]))
    expect(peer, fixture, "scan", ok,
           [SCAN, "4 points on the part (1 off it dropped)", "7.50 mm"],
           "scan in a frame from /tf_static")

    # Arc faults: a late one is refused; a good one while nothing is welded stops nothing.
    fault = lambda offset_s: arc_fault.publish(  # noqa: E731
        Header(stamp=stamp(peer, offset_s), frame_id="welder"))
    expect(peer, lambda: fault(-10.0), "arc fault", warn, [ARC_FAULT, "late", "max_age_s"],
           "arc fault 10 s late")
    expect(peer, lambda: fault(0.0), "arc fault", ok, [ARC_FAULT, "nothing stopped"],
           "arc fault with no weld path running")

    # The planner's component stayed OK throughout, and the node is up.
    last = peer.received["/diagnostics"][-1]
    planner = [s for s in last.status if s.name == "cellX/waam_planner: planner"]
    check(planner and waamtest.level(planner[0]) == ok, f"planner status: {planner}")
    check(waam.alive(), "waam node exited")


waamtest.run(test, "node", "--record", sys.argv[1], "--ros-args", "-r", "__ns:=/cellX")
