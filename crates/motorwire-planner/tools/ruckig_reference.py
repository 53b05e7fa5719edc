#!/usr/bin/env python3
"""Ruckig's time-optimal durations for seeded random full-state requests.

The reference for motorwire-planner's differential test
`tests/ruckig_reference.rs`. Ruckig (the C++ library, through its Python
package; the test is written against 0.19.4) plans each 1-DoF request and
this prints one CSV line per request:

    start,target,start_velocity,target_velocity,max_velocity,max_acceleration,max_jerk,duration

every number as Python's `repr` (the shortest string that reads back as the
same f64). Deceleration equals acceleration (Ruckig's `min_acceleration`
defaults to `-max_acceleration`); start and target velocities are uniform
in [-max_velocity, max_velocity]. A request Ruckig fails on is printed with
the duration `nan`. Lines starting with `#` are comments: the first names
the version, seed and count, the last the time Ruckig's `calculate` took
per call (measured around that call alone, Python's overhead of the call
included).

    python3 ruckig_reference.py --seed 17 --count 100000 > ruckig.csv

With `--time PASSES` it instead reads requests from stdin, one a line,
`start,target,start_velocity,target_velocity,max_velocity,max_acceleration,min_acceleration,max_jerk`
(`min_acceleration` negative), plans all of them PASSES times and prints
`ruckig python: N ns per call` (the median pass; Python's overhead of the
call included). The planner benchmark uses it to time Ruckig on its own
requests in the same run.
"""

import argparse
import math
import random
import sys
import time

import ruckig


def request(rng):
    """One random full-state request, from one of three sets of ranges."""
    kind = rng.randrange(3)
    if kind == 0:
        # The ranges of a servo joint in degrees (and of the example).
        vmax = rng.uniform(10.0, 200.0)
        acc = rng.uniform(50.0, 2000.0)
        jerk = rng.uniform(100.0, 20000.0)
        p0 = rng.uniform(-180.0, 180.0)
        p1 = rng.uniform(-180.0, 180.0)
    elif kind == 1:
        # Limits over many decades, distances from tiny to long.
        vmax = 10.0 ** rng.uniform(-2.0, 3.0)
        acc = 10.0 ** rng.uniform(-1.0, 4.0)
        jerk = 10.0 ** rng.uniform(0.0, 6.0)
        p0 = rng.uniform(-100.0, 100.0)
        p1 = p0 + rng.choice((-1.0, 1.0)) * 10.0 ** rng.uniform(-4.0, 3.0)
    else:
        # Short moves relative to the boundary velocities: the region where
        # the profile must brake, back up or pass the target.
        vmax = 10.0 ** rng.uniform(-1.0, 2.0)
        acc = 10.0 ** rng.uniform(-1.0, 3.0)
        jerk = 10.0 ** rng.uniform(0.0, 4.0)
        p0 = rng.uniform(-10.0, 10.0)
        # The distance of the stop from vmax, scaled down by up to 1e4.
        stop = vmax * vmax / acc + vmax * acc / jerk
        p1 = p0 + rng.choice((-1.0, 1.0)) * stop * 10.0 ** rng.uniform(-4.0, 0.5)
    v0 = rng.uniform(-vmax, vmax)
    v1 = rng.uniform(-vmax, vmax)
    return (p0, p1, v0, v1, vmax, acc, jerk)


def time_requests(passes):
    """Times Ruckig's calculate on the requests read from stdin."""
    inputs = []
    for line in sys.stdin:
        line = line.strip()
        if not line or line.startswith("#"):
            continue
        p0, p1, v0, v1, vmax, amax, amin, jerk = (float(f) for f in line.split(","))
        inp = ruckig.InputParameter(1)
        inp.current_position = [p0]
        inp.target_position = [p1]
        inp.current_velocity = [v0]
        inp.target_velocity = [v1]
        inp.max_velocity = [vmax]
        inp.max_acceleration = [amax]
        inp.min_acceleration = [amin]
        inp.max_jerk = [jerk]
        inputs.append(inp)
    otg = ruckig.Ruckig(1)
    traj = ruckig.Trajectory(1)
    per_pass = []
    failed = 0
    for _ in range(passes):
        t0 = time.perf_counter_ns()
        for inp in inputs:
            if otg.calculate(inp, traj) != ruckig.Result.Working:
                failed += 1
        per_pass.append((time.perf_counter_ns() - t0) / max(len(inputs), 1))
    per_pass.sort()
    print(
        "ruckig python: %.1f ns per call (median of %d passes over %d requests, %d failed)"
        % (per_pass[len(per_pass) // 2], passes, len(inputs), failed)
    )


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--seed", type=int)
    parser.add_argument("--count", type=int)
    parser.add_argument("--time", type=int, metavar="PASSES")
    args = parser.parse_args()
    if args.time is not None:
        time_requests(args.time)
        return
    if args.seed is None or args.count is None:
        parser.error("--seed and --count are required (or --time)")

    rng = random.Random(args.seed)
    otg = ruckig.Ruckig(1)
    traj = ruckig.Trajectory(1)
    inp = ruckig.InputParameter(1)
    out = sys.stdout
    out.write("# ruckig %s seed %d count %d\n" % (ruckig.__version__, args.seed, args.count))
    spent = 0
    for _ in range(args.count):
        p0, p1, v0, v1, vmax, acc, jerk = request(rng)
        inp.current_position = [p0]
        inp.current_velocity = [v0]
        inp.current_acceleration = [0.0]
        inp.target_position = [p1]
        inp.target_velocity = [v1]
        inp.target_acceleration = [0.0]
        inp.max_velocity = [vmax]
        inp.max_acceleration = [acc]
        inp.max_jerk = [jerk]
        t0 = time.perf_counter_ns()
        result = otg.calculate(inp, traj)
        spent += time.perf_counter_ns() - t0
        duration = traj.duration if result == ruckig.Result.Working else math.nan
        out.write(",".join(repr(x) for x in (p0, p1, v0, v1, vmax, acc, jerk, duration)))
        out.write("\n")
    out.write("# ruckig calculate: %.3f us per call (Python binding included)\n" % (spent / 1e3 / max(args.count, 1)))


if __name__ == "__main__":
    main()
