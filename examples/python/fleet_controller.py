#!/usr/bin/env python3
"""A fleet controller for motorwire bridges on Zenoh.

Finds every bridge by its liveliness token (motorwire/<robot>/alive), sends
each the same synchronized multi-axis move at the same moment (one query on
motorwire/<robot>/cmd/<controller> each: the ids of its commands are this
controller's own), prints each result and arrival as it comes,
then puts the fleet's emergency stop (motorwire/fleet/estop) and prints
each bridge's stop result.

Needs eclipse-zenoh==1.10.2 (the version of the bridges' Rust zenoh):

    python3 -m venv venv && venv/bin/pip install eclipse-zenoh==1.10.2
    venv/bin/python examples/python/fleet_controller.py --listen tcp/127.0.0.1:7447

With --listen this controller is where the bridges connect (no router
needed on one machine); with --config FILE it uses a Zenoh configuration
such as crates/motorwire-zenoh/config/controller.json5 (TLS, a password;
--controller is then the Zenoh user, the only one the router lets ask on
motorwire/*/cmd/<user>).
Exit status 0 when every bridge found arrived and stopped, 1 otherwise.
"""

import argparse
import json
import sys
import threading
import time

import zenoh


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    where = p.add_mutually_exclusive_group()
    where.add_argument("--listen", metavar="ENDPOINT", help="listen for bridges here (peer mode), e.g. tcp/127.0.0.1:7447")
    where.add_argument("--connect", metavar="ENDPOINT", help="connect to a router or peer here, e.g. tcp/127.0.0.1:7447")
    where.add_argument("--config", metavar="FILE", help="a Zenoh configuration file (JSON5)")
    p.add_argument("--expect", type=int, default=1, help="wait until this many bridges are alive (default 1)")
    p.add_argument("--wait", type=float, default=60.0, help="seconds to wait for them (default 60)")
    p.add_argument("--position", type=float, default=30.0, help="the elbow's target (degrees, default 30)")
    p.add_argument("--duration-ms", type=int, default=1500, help="the move's duration (default 1500 ms)")
    p.add_argument("--release", action="store_true", help="release each robot's stop at the end")
    p.add_argument(
        "--controller",
        default="controller",
        help="this controller's name, the last chunk of motorwire/<robot>/cmd/<controller> (default controller, the user of config/controller.json5)",
    )
    return p.parse_args()


def open_session(args):
    if args.config:
        conf = zenoh.Config.from_file(args.config)
    else:
        conf = zenoh.Config()
        conf.insert_json5("scouting/multicast/enabled", "false")
        if args.listen:
            conf.insert_json5("mode", '"peer"')
            conf.insert_json5("listen/endpoints", json.dumps([args.listen]))
        elif args.connect:
            conf.insert_json5("mode", '"client"')
            conf.insert_json5("connect/endpoints", json.dumps([args.connect]))
    return zenoh.open(conf)


def alive(session):
    """The robots whose liveliness token is seen now."""
    robots = set()
    for reply in session.liveliness().get("motorwire/*/alive", timeout=2.0):
        if reply.ok is not None:
            robots.add(str(reply.ok.key_expr).split("/")[1])
    return sorted(robots)


def discover(session, expect, wait):
    end = time.monotonic() + wait
    robots = alive(session)
    while len(robots) < expect and time.monotonic() < end:
        time.sleep(0.2)
        robots = alive(session)
    return robots


def move(session, robot, controller, command, results):
    """One command query; every reply printed and kept, in order."""
    replies = session.get(
        f"motorwire/{robot}/cmd/{controller}",
        payload=json.dumps(command),
        consolidation=zenoh.ConsolidationMode.NONE,
        timeout=30.0,
    )
    lines = []
    for reply in replies:
        if reply.ok is None:
            print(f"{robot}: error reply {reply.err.payload.to_string()}", flush=True)
            continue
        line = json.loads(reply.ok.payload.to_string())
        lines.append(line)
        kind = "arrival" if "arrived" in line else "result"
        print(f"{robot}: {kind} {json.dumps(line)}", flush=True)
    results[robot] = lines


def main():
    args = parse_args()
    session = open_session(args)
    stop_results, expected, all_stopped = [], [0], threading.Event()

    def on_stop_result(sample):
        stop_results.append(sample)
        if expected[0] and len(stop_results) >= expected[0]:
            all_stopped.set()

    session.declare_subscriber("motorwire/*/estop/result", on_stop_result)

    robots = discover(session, args.expect, args.wait)
    print(f"bridges alive: {robots}", flush=True)
    if len(robots) < args.expect:
        print(f"expected {args.expect}, found {len(robots)}", file=sys.stderr)
        return 1

    # One synchronized move, the same for every robot, sent at once. Its
    # command_id is its id: a retry of the same query is never run twice.
    stamp = int(time.time() * 1000)
    results, threads = {}, []
    for robot in robots:
        command = {
            "command_id": f"fleet-{stamp}-{robot}",
            "timestamp": stamp,
            "sync_mode": "simultaneous",
            "motors": [
                {"motor_id": "shoulder_pitch", "control_mode": "position", "setpoint": args.position / 3},
                {"motor_id": "elbow", "control_mode": "position", "setpoint": args.position},
            ],
            "coordination": {"type": "linear_interpolation", "total_duration_ms": args.duration_ms},
        }
        t = threading.Thread(target=move, args=(session, robot, args.controller, command, results))
        t.start()
        threads.append(t)
    for t in threads:
        t.join()
    arrived = [r for r in robots if any(l.get("arrived") is True for l in results.get(r, []))]
    print(f"arrived: {arrived}", flush=True)

    # The fleet's emergency stop: one put, every bridge.
    expected[0] = len(robots)
    sent = time.monotonic()
    session.put("motorwire/fleet/estop", "{}")
    all_stopped.wait(5.0)
    took = (time.monotonic() - sent) * 1000
    stopped = sorted(str(s.key_expr).split("/")[1] for s in stop_results)
    for s in stop_results:
        print(f"{str(s.key_expr).split('/')[1]}: stop {s.payload.to_string()}", flush=True)
    print(f"stopped: {stopped} ({took:.1f} ms from the put to the last stop result)", flush=True)

    if args.release:
        for robot in robots:
            for reply in session.get(
                f"motorwire/{robot}/cmd/{args.controller}",
                payload='{"emergency_stop": false}',
                consolidation=zenoh.ConsolidationMode.NONE,
                timeout=5.0,
            ):
                if reply.ok is not None:
                    print(f"{robot}: release {reply.ok.payload.to_string()}", flush=True)
    session.close()
    return 0 if arrived == robots and stopped == robots else 1


if __name__ == "__main__":
    sys.exit(main())
