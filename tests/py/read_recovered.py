"""Reads killed recordings before and after `waam bag reindex` with every Python reader.

Usage: read_recovered.py BEFORE_MCAP BAG_DIR [BEFORE_MCAP BAG_DIR ...]

BEFORE_MCAP is a copy of a bag's file as the killed process left it; BAG_DIR the bag after
`waam bag reindex`. Before: the MCAP stream reader (NonSeekingReader, decoding with
mcap-ros2-support) reads what was flushed. After, three readers read the bag:
- "stream": the same stream reader, decoding every message;
- "indexed": `make_reader` on the file, as docs/recording.md shows: the seeking reader, which
  reads through the summary's chunk indexes (no summary, no messages), decoding every message;
- "rosbags": `rosbags.rosbag2.Reader` on the directory (metadata.yaml, then the MCAP file),
  deserializing every message.
Prints one JSON object per bag, in order: {"before": n, "readers": {name: {"count": n,
"same": bool, "part": n, "error": str|null}}, "rosbags_metadata_count": n}. "same": the reader
read exactly the messages the stream reader read before (topic, log time, sequence, bytes).
"""

import hashlib
import json
import sys
from pathlib import Path

from mcap.reader import NonSeekingReader, SeekingReader, make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore, get_types_from_msg

PART = "/waam_planner/part"


def key(topic, log_time, data):
    return (topic, log_time, hashlib.sha1(bytes(data)).hexdigest())


def read_stream(path):
    keys = []
    with open(path, "rb") as f:
        reader = NonSeekingReader(f, decoder_factories=[DecoderFactory()])
        try:
            for _, channel, message, _ in reader.iter_decoded_messages(log_time_order=False):
                keys.append(key(channel.topic, message.log_time, message.data))
        except Exception:  # the cut of a killed file: what came before it counts
            pass
    return keys


def read_indexed(path):
    keys = []
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        if not isinstance(reader, SeekingReader):
            raise RuntimeError(f"make_reader gave a {type(reader).__name__}")
        if reader.get_summary() is None:
            raise RuntimeError("no summary")
        for _, channel, message, _ in reader.iter_decoded_messages(log_time_order=False):
            keys.append(key(channel.topic, message.log_time, message.data))
    return keys


def read_rosbags(bag_dir):
    keys = []
    store = get_typestore(Stores.ROS2_JAZZY)
    with Reader(bag_dir) as reader:
        ours = {}
        for c in reader.connections:
            if c.msgtype not in store.types:
                ours.update(get_types_from_msg(c.msgdef.data, c.msgtype))
        store.register(ours)
        for connection, timestamp, raw in reader.messages():
            store.deserialize_cdr(raw, connection.msgtype)
            keys.append(key(connection.topic, timestamp, raw))
        return keys, reader.message_count


def main():
    args = sys.argv[1:]
    for before_path, bag_dir in zip(args[::2], args[1::2]):
        before = read_stream(before_path)
        mcap_file = sorted(Path(bag_dir).glob("*.mcap"))[0]
        readers = {}
        metadata_count = None
        for name, read in [
            ("stream", lambda: read_stream(mcap_file)),
            ("indexed", lambda: read_indexed(mcap_file)),
            ("rosbags", lambda: read_rosbags(bag_dir)),
        ]:
            error = None
            try:
                keys = read()
                if name == "rosbags":
                    keys, metadata_count = keys
            except Exception as e:
                keys, error = [], f"{type(e).__name__}: {e}"
            readers[name] = {
                "count": len(keys),
                "same": sorted(keys) == sorted(before),
                "part": sum(1 for k in keys if k[0] == PART),
                "error": error,
            }
        print(json.dumps({"before": len(before), "readers": readers,
                          "rosbags_metadata_count": metadata_count}))


main()
