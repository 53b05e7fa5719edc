#!/usr/bin/env python3
"""Stream setpoints from a policy loop to a running `motorwire bridge`, with the standard library only.

A learned policy sends a new position setpoint every tick (30 to 500 Hz).
Each line carries `"stream": true`: the bridge answers each with one result
(`ok`, `"arrival_follows": false`) and no completion line, a setpoint
replaced by a newer one before it went out is answered `ok` with
`"superseded": true`, and a refused one carries its `rule`. This script
streams a sine to the elbow from where it stands, reads the answers as they
come (on a thread of their own: results may come out of line order), and
reports how many came back of which kind and how closely the elbow's
feedback followed the stream.

    motorwire bridge --map fixtures/maps/demo-arm.toml --bus sim --feedback-hz 50 --input unix: &
    python3 examples/python/stream_policy.py --unix --hz 100 --seconds 3

With `--with MOTOR` (repeatable) each tick is one multi-axis line, also
`"stream": true`, that sets the elbow and a 10-degree sine about where each
other motor stands: one line and one result a tick, however many motors.

It exits 1 if a line gets no result, a result is not `ok`, or a completion
line comes for a stream's setpoint (so CI runs it), 0 otherwise.
"""

import argparse
import json
import math
import socket
import sys
import threading
import time

from bridge_client import Bridge, default_socket


def policy(t, start):
    """The policy's action at time t (s): a 0.5 Hz sine of 20 degrees
    about where the elbow stood."""
    return start + 20.0 * math.sin(2.0 * math.pi * 0.5 * t)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--unix", metavar="PATH", nargs="?", const=default_socket(), default=default_socket(),
                        help="the bridge's --input unix:PATH socket (default: the bridge's own default)")
    parser.add_argument("--motor", default="elbow")
    parser.add_argument("--with", dest="others", action="append", default=[], metavar="MOTOR",
                        help="another motor set in the same line each tick (a multi-axis stream line)")
    parser.add_argument("--hz", type=float, default=100.0, help="setpoints a second (default 100)")
    parser.add_argument("--seconds", type=float, default=3.0, help="how long to stream (default 3)")
    args = parser.parse_args()

    bridge = Bridge.unix(args.unix)
    ready = bridge.wait_event("ready")
    motor = next(m for m in ready["motors"] if m["motor_id"] == args.motor)
    here = motor.get("position", 0.0)
    # The sine swings 20 degrees each way: it starts where the elbow stands
    # if that leaves room inside its 0..150, else the elbow is moved first.
    start = min(max(here, 25.0), 125.0)
    if abs(start - here) > 0.01:
        line = bridge.send({"motor_id": args.motor, "timestamp": int(time.time() * 1000),
                            "control_mode": "position", "setpoint": start})
        if bridge.wait_for(line, "ok").get("ok") is not True:
            raise RuntimeError("the move to %s was refused" % start)
        bridge.wait_for(line, "arrived")
    others = {m["motor_id"]: m.get("position", 0.0) for m in ready["motors"] if m["motor_id"] in args.others}
    if len(others) != len(args.others):
        raise RuntimeError("not motors of the bridge: %s" % sorted(set(args.others) - set(others)))
    first = bridge.sent

    results, arrivals, feedback = {}, [], []
    sent_at = {}
    done = threading.Event()

    def reader():
        while not done.is_set():
            try:
                message = bridge.read()
            except (OSError, ValueError, ConnectionError):
                return
            if "ok" in message and "line" in message and message["line"] > first:
                results[message["line"]] = message
            elif "arrived" in message and message.get("line", 0) > first:
                arrivals.append(message)
            elif "feedback" in message:
                for f in message["feedback"] if isinstance(message["feedback"], list) else [message["feedback"]]:
                    if f.get("motor_id") == args.motor:
                        feedback.append((time.monotonic(), f["position"]))

    thread = threading.Thread(target=reader, daemon=True)
    thread.start()

    period = 1.0 / args.hz
    t0 = time.monotonic()
    tick = 0
    while True:
        t = tick * period
        if t >= args.seconds:
            break
        now_ms = int(time.time() * 1000)
        setpoint = round(policy(t, start), 4)
        if others:
            # One line for every motor of the tick: one result.
            axes = [{"motor_id": args.motor, "control_mode": "position", "setpoint": setpoint}]
            axes += [{"motor_id": m, "control_mode": "position",
                      "setpoint": round(p + 0.5 * (policy(t, 0.0)), 4)} for m, p in others.items()]
            line = bridge.send({"command_id": "tick%d" % tick, "timestamp": now_ms,
                                "motors": axes, "stream": True})
        else:
            line = bridge.send({"motor_id": args.motor, "timestamp": now_ms,
                                "control_mode": "position", "setpoint": setpoint, "stream": True})
        sent_at[line] = t0 + t
        tick += 1
        # The next tick, on the loop's own clock (no drift).
        pause = t0 + tick * period - time.monotonic()
        if pause > 0:
            time.sleep(pause)

    # Every line answered (at most 5 s more).
    deadline = time.monotonic() + 5.0
    while len(results) < tick and time.monotonic() < deadline:
        time.sleep(0.01)
    time.sleep(0.2)
    done.set()

    failed = False
    missing = [n for n in range(first + 1, first + tick + 1) if n not in results]
    not_ok = [r for r in results.values() if r.get("ok") is not True]
    follows = [r for r in results.values() if r.get("ok") and r.get("arrival_follows") is not False]
    superseded = sum(1 for r in results.values() if r.get("superseded"))
    print("%d setpoints at %.0f Hz: %d results, %d superseded before they went out, %d completion lines"
          % (tick, args.hz, len(results), superseded, len(arrivals)))
    if missing:
        print("FAIL: no result for lines %s" % missing[:10], file=sys.stderr)
        failed = True
    if not_ok:
        print("FAIL: not ok: %s" % json.dumps(not_ok[:3]), file=sys.stderr)
        failed = True
    if follows or arrivals:
        print("FAIL: a stream's setpoint promised or got a completion line", file=sys.stderr)
        failed = True
    # How closely the feedback followed the stream (the policy's action
    # at the time each feedback line came).
    errors = [p - policy(t - t0, start) for t, p in feedback if 0.5 < t - t0 < args.seconds]
    if errors:
        rms = math.sqrt(sum(e * e for e in errors) / len(errors))
        print("the %s's feedback against the stream: RMS %.2f deg, max %.2f deg (%d feedback lines)"
              % (args.motor, rms, max(abs(e) for e in errors), len(errors)))
    bridge.close()
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    try:
        main()
    except (OSError, ValueError, KeyError, RuntimeError, socket.timeout) as e:
        print("FAIL: %s: %s" % (type(e).__name__, e), file=sys.stderr)
        sys.exit(1)
