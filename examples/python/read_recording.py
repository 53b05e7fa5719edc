#!/usr/bin/env python3
"""Read a `motorwire bridge --record DIR` recording with python-can.

`DIR/frames.log` is a `candump -L` log: python-can's `can.LogReader` reads
it as it reads any candump log (and can-utils' `canplayer -I` replays it).
`DIR/lines.jsonl` holds the same frames with their direction, between the
input lines (`"in"`), the output lines (`"out"`: results, completions,
feedback, events) and the Orion controller's lines (`"orion"`), each with
`t_us` on one monotonic clock and `wall_ms`.

    motorwire bridge --map fixtures/maps/demo-arm.toml --bus sim --record rec < lines
    python3 -m venv venv && venv/bin/pip install python-can
    venv/bin/python examples/python/read_recording.py rec

It prints what the session held, and exits 1 if the two files disagree on
a single frame (its id, its bytes, CAN FD or not, its order), 0 otherwise.
"""

import json
import os
import sys

import can


def main(directory):
    frames = list(can.LogReader(os.path.join(directory, "frames.log")))
    lines = []
    with open(os.path.join(directory, "lines.jsonl"), encoding="utf-8") as f:
        for text in f:
            lines.append(json.loads(text))
    recorded = [r["frame"] for r in lines if "frame" in r]
    rotated = any(os.path.exists(os.path.join(directory, f)) for f in ("frames.1.log", "lines.1.jsonl"))
    if rotated:
        # The two files rotate apart: compare the frames both still hold
        # (the latest ones).
        n = min(len(frames), len(recorded))
        frames, recorded = frames[len(frames) - n:], recorded[len(recorded) - n:]
    elif len(frames) != len(recorded):
        print("FAIL: %d frames in frames.log, %d in lines.jsonl" % (len(frames), len(recorded)),
              file=sys.stderr)
        return 1
    for i, (m, r) in enumerate(zip(frames, recorded)):
        same = (m.arbitration_id == r["id"]
                and m.is_extended_id == r["extended"]
                and m.is_fd == r["fd"]
                and bytes(m.data).hex() == r["data"])
        if not same:
            print("FAIL: frame %d: %s in frames.log, %s in lines.jsonl" % (i, m, json.dumps(r)),
                  file=sys.stderr)
            return 1
    inputs = [r["in"] for r in lines if "in" in r]
    # Each result with the client it went to ("to"): two clients each
    # have a line 1.
    results = [dict(r["out"], to=r.get("to")) for r in lines
               if "out" in r and "ok" in r["out"] and "event" not in r["out"]]
    sent = sum(1 for r in recorded if r["dir"] == "tx")
    orion = sum(1 for r in lines if "orion" in r)
    print("frames: %d (%d sent, %d received), read by python-can %s the same as lines.jsonl has them"
          % (len(frames), sent, len(frames) - sent, can.__version__))
    print("input lines: %d, results: %d (%d ok), Orion lines: %d"
          % (len(inputs), len(results), sum(1 for r in results if r["ok"]), orion))
    for i in inputs:
        answer = next((r for r in results
                       if r.get("line") == i["line"] and r["to"] == i["origin"]), None)
        print("  line %d: %s -> %s" % (i["line"], i.get("text", i.get("unreadable")),
                                       "ok" if answer and answer["ok"] else
                                       (answer or {}).get("error", {}).get("rule", "no result")))
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 2:
        print("usage: read_recording.py DIR", file=sys.stderr)
        sys.exit(2)
    sys.exit(main(sys.argv[1]))
