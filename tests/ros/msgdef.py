"""A small, independent decoder of ROS 2 CDR bytes driven by `.msg` files.

The tests use it to check that what waam_planner sends on ~/plan/weld_plan decodes against
the interface package's own definitions (ros/waam_interfaces/msg/*.msg), without trusting
the Rust types that produced the bytes. Standard types come from the Jazzy definitions
vendored in crates/rosmsg/src/defs/. Plain CDR (XCDR1), little or big endian, as rmw_fastrtps sends.
"""

import os
import re
import struct

# The repository root (this file is tests/ros/msgdef.py); no rclpy needed here.
REPO = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

SEARCH = [
    os.path.join(REPO, "ros"),  # ros/<pkg>/msg/<Name>.msg (our interface package)
    os.path.join(REPO, "crates", "rosmsg", "src", "defs"),  # crates/rosmsg/src/defs/<pkg>/<Name>.msg
]

PRIMITIVES = {
    "bool": ("?", 1),
    "byte": ("B", 1),
    "char": ("B", 1),
    "uint8": ("B", 1),
    "int8": ("b", 1),
    "uint16": ("H", 2),
    "int16": ("h", 2),
    "uint32": ("I", 4),
    "int32": ("i", 4),
    "float32": ("f", 4),
    "uint64": ("Q", 8),
    "int64": ("q", 8),
    "float64": ("d", 8),
}


def find_msg(package, name):
    for root in SEARCH:
        for path in (
            os.path.join(root, package, "msg", name + ".msg"),
            os.path.join(root, package, name + ".msg"),
        ):
            if os.path.exists(path):
                return path
    raise FileNotFoundError(f"no definition of {package}/msg/{name} under {SEARCH}")


def fields(package, name):
    """[(field name, base type, array: None | 'unbounded' | N)] of a .msg file."""
    out = []
    with open(find_msg(package, name), encoding="utf-8") as f:
        for line in f:
            line = line.split("#", 1)[0].strip()
            if not line:
                continue
            type_, rest = line.split(None, 1)
            rest = rest.strip()
            if "=" in rest.split()[0] or re.match(r"^\w+\s*=", rest):
                continue  # a constant
            field = rest.split()[0]
            array = None
            m = re.match(r"^(.*)\[(<=)?(\d*)\]$", type_)
            if m:
                type_ = m.group(1)
                array = int(m.group(3)) if m.group(3) and not m.group(2) else "unbounded"
            type_ = re.sub(r"<=\d+$", "", type_)  # bounded string
            out.append((field, type_, array))
    return out


class Reader:
    def __init__(self, data):
        if len(data) < 4:
            raise ValueError("shorter than the encapsulation header")
        if data[0:2] == b"\x00\x01":
            self.endian = "<"
        elif data[0:2] == b"\x00\x00":
            self.endian = ">"
        else:
            raise ValueError(f"unknown encapsulation {data[0:2].hex()}")
        self.data = data[4:]
        self.pos = 0

    def align(self, n):
        self.pos += (-self.pos) % n

    def prim(self, type_):
        code, size = PRIMITIVES[type_]
        self.align(size)
        if self.pos + size > len(self.data):
            raise ValueError(f"ran out of bytes reading {type_} at {self.pos}")
        (v,) = struct.unpack_from(self.endian + code, self.data, self.pos)
        self.pos += size
        return v

    def string(self):
        n = self.prim("uint32")
        raw = self.data[self.pos : self.pos + n]
        if len(raw) != n or (n and raw[-1] != 0):
            raise ValueError(f"bad string of length {n} at {self.pos}")
        self.pos += n
        return raw[:-1].decode("utf-8")


def decode_type(reader, package, type_):
    if type_ in PRIMITIVES:
        return reader.prim(type_)
    if type_ == "string":
        return reader.string()
    if "/" in type_:
        package, name = type_.split("/")[0], type_.split("/")[-1]
    elif type_ == "Header":
        package, name = "std_msgs", "Header"
    else:
        name = type_
    return {
        field: decode_field(reader, package, base, array)
        for field, base, array in fields(package, name)
    }


def decode_field(reader, package, base, array):
    if array is None:
        return decode_type(reader, package, base)
    n = reader.prim("uint32") if array == "unbounded" else array
    return [decode_type(reader, package, base) for _ in range(n)]


def decode(data, type_name):
    """Decodes CDR bytes (with header) of `pkg/msg/Name`; fails on leftover bytes."""
    package, _, name = type_name.split("/")
    reader = Reader(bytes(data))
    value = decode_type(reader, package, f"{package}/{name}")
    leftover = len(reader.data) - reader.pos
    if leftover >= 4:  # CDR may pad the end to 4 bytes, never more
        raise ValueError(f"{leftover} bytes left after decoding {type_name}")
    return value
