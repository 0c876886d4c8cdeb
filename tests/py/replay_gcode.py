"""Replays a G-code file with pygcode: prints one JSON object per line for every motion
({"g": 0|1, "xyz": [x, y, z], "feed": F or null, "arc": bool}) and every dwell
({"dwell": seconds, "arc": bool}). The arc state follows the arc-on / arc-off commands
given on the command line (as words, e.g. M3 M5).

usage: replay_gcode.py FILE.gcode ARC_ON ARC_OFF
"""
import json
import sys

from pygcode import Line, Machine, Word, GCodeLinearMove, GCodeRapidMove, GCodeDwell


def word_key(w):
    """A word as (letter, number): M3 and M03 are the same command."""
    return (w.letter.upper(), float(w.value))


def main() -> None:
    path = sys.argv[1]
    arc_on, arc_off = (word_key(Word(w)) for w in sys.argv[2:4])
    machine = Machine()
    arc = False
    feed = None
    with open(path) as f:
        for text in f:
            line = Line(text)
            if not line.block.words:
                continue
            words = [word_key(w) for w in line.block.words]
            for w in line.block.words:
                if str(w).upper().startswith("F"):
                    feed = float(w.value)
            for gcode in sorted(line.block.gcodes):
                machine.process_gcodes(gcode)
                if isinstance(gcode, (GCodeLinearMove, GCodeRapidMove)):
                    p = machine.pos
                    print(json.dumps({
                        "g": 0 if isinstance(gcode, GCodeRapidMove) else 1,
                        "xyz": [p.X, p.Y, p.Z],
                        "feed": feed,
                        "arc": arc,
                    }))
                elif isinstance(gcode, GCodeDwell):
                    print(json.dumps({"dwell": float(gcode.P), "arc": arc}))
            if arc_on in words:
                arc = True
            if arc_off in words:
                arc = False


main()
