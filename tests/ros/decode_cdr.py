"""Decodes a file of raw CDR bytes against our .msg definitions and prints it as JSON.

Usage: decode_cdr.py FILE pkg/msg/Type
"""

import json
import sys

import msgdef

with open(sys.argv[1], "rb") as f:
    value = msgdef.decode(f.read(), sys.argv[2])
json.dump(value, sys.stdout, allow_nan=True)
