#!/usr/bin/env python3
"""Profiles from a start acceleration against Ruckig itself.

Seeded random full-state requests in a servo joint's ranges (degrees:
velocity limits 10-200, acceleration 50-2000, jerk 100-20,000, positions in
+-180, start velocity within the limit, start acceleration within the
limit, target at rest), planned by Ruckig 0.19.4 (its Python package) and
by `motorwire plan` (the path to the binary is the first argument); prints
how motorwire's durations compare. Requests Ruckig refuses are skipped.

    python3 ruckig_start_acceleration.py target/release/motorwire --count 20000

"Velocity limit passed on the way" counts requests whose start state must
pass the velocity limit whatever is done (bringing the acceleration to
zero at the jerk limit already passes it): there the two differ in how
they come back under it.
"""

import argparse
import json
import random
import subprocess

import ruckig


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("motorwire")
    parser.add_argument("--count", type=int, default=20000)
    parser.add_argument("--seed", type=int, default=26)
    args = parser.parse_args()
    rng = random.Random(args.seed)
    requests, reference = [], []
    while len(requests) < args.count:
        vmax = rng.uniform(10.0, 200.0)
        amax = rng.uniform(50.0, 2000.0)
        jmax = rng.uniform(100.0, 20000.0)
        p0, p1 = rng.uniform(-180.0, 180.0), rng.uniform(-180.0, 180.0)
        v0, a0 = rng.uniform(-vmax, vmax), rng.uniform(-amax, amax)
        inp = ruckig.InputParameter(1)
        inp.current_position, inp.current_velocity, inp.current_acceleration = [p0], [v0], [a0]
        inp.target_position, inp.target_velocity, inp.target_acceleration = [p1], [0.0], [0.0]
        inp.max_velocity, inp.max_acceleration, inp.max_jerk = [vmax], [amax], [jmax]
        traj = ruckig.Trajectory(1)
        try:
            result = ruckig.Ruckig(1).calculate(inp, traj)
        except Exception:  # RuckigError: a request it cannot plan
            continue
        if result not in (ruckig.Result.Working, ruckig.Result.Finished):
            continue
        requests.append({
            "start": p0, "target": p1, "start_velocity": v0, "start_acceleration": a0,
            "max_velocity": vmax, "max_acceleration": amax, "max_jerk": jmax, "profile": "scurve",
        })
        reference.append(traj.duration)
    out = subprocess.run(
        [args.motorwire, "plan"],
        input="".join(json.dumps(r) + "\n" for r in requests),
        capture_output=True, text=True, check=False,
    ).stdout.splitlines()
    counts = {"equal": 0, "shorter": 0, "longer": 0, "failed": 0}
    passed = {"shorter": 0, "longer": 0}
    worst = 1.0
    for line, r, ref in zip(out, requests, reference):
        o = json.loads(line)
        if "duration" not in o:
            counts["failed"] += 1
            continue
        ratio = o["duration"] / ref if ref > 0 else 1.0
        a0, j = r["start_acceleration"], r["max_jerk"]
        inevitable = abs(r["start_velocity"] + a0 * abs(a0) / (2 * j)) > r["max_velocity"]
        kind = "equal" if abs(ratio - 1) <= 1e-6 else ("shorter" if ratio < 1 else "longer")
        counts[kind] += 1
        if kind != "equal" and inevitable:
            passed[kind] += 1
        if kind == "longer":
            worst = max(worst, ratio)
    print(f"ruckig 0.19.4, "
          f"{len(requests)} requests (seed {args.seed}): equal within 1e-6 {counts['equal']}, "
          f"shorter {counts['shorter']} (velocity limit passed on the way: {passed['shorter']}), "
          f"longer {counts['longer']} (velocity limit passed on the way: {passed['longer']}; "
          f"at most {worst:.3f}x), failed {counts['failed']}")


if __name__ == "__main__":
    main()
