"""Reads an MCAP file cut short (a killed recording) with the Python MCAP stream reader.

Usage: read_truncated.py MCAP_FILE

Decodes every message it can (mcap-ros2-support), stops at the first error, and prints JSON:
{"messages": n, "topics": {topic: n}, "error": "..." or null, "last_log_time": ns}.
"""

import json
import sys
from collections import Counter

from mcap.reader import NonSeekingReader
from mcap_ros2.decoder import DecoderFactory

counts = Counter()
error = None
last = None
with open(sys.argv[1], "rb") as f:
    reader = NonSeekingReader(f, decoder_factories=[DecoderFactory()])
    try:
        for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=False):
            counts[channel.topic] += 1
            last = message.log_time
    except Exception as e:  # the cut: the reader says where it could not go on
        error = f"{type(e).__name__}: {e}"
print(json.dumps({"messages": sum(counts.values()), "topics": counts, "error": error,
                  "last_log_time": last}))
