#!/usr/bin/env python3
"""Unmodified LeRobot motor-bus code (lerobot 0.4.4's `FeetechMotorsBus` and
`DynamixelMotorsBus`) against `motorwire sim servos` on a pseudo-terminal.

For an SO-101 arm (six STS3215, Feetech protocol 0) and a Koch-style arm
(six XL330-M288, Dynamixel Protocol 2.0), it does what LeRobot does with
a real arm, through LeRobot's own serial code (the vendors' SDKs on
pyserial) and nothing of motorwire's but the simulated servos:

- `connect()` (its handshake pings every motor, checks its model number and
  reads its firmware), `broadcast_ping()` (every id, with its model);
- `configure_motors()`, `disable_torque()`, `set_half_turn_homings()` (the
  homing offset that makes the middle pose read half a turn, written to
  the EEPROM and read back), `write_calibration()` and `read_calibration()`
  of the ranges;
- `enable_torque()`, `sync_write("Goal_Position")` with normalized values,
  then `sync_read("Present_Position")` while the servos move and once they
  arrived (within a step of the goal), `read` of every register a robot
  reads (`Present_Velocity`, `Present_Load`, `Present_Temperature`, ...);
- `disconnect()` (torque off).

LeRobot's heavy dependencies (torch, accelerate, datasets and what they
pull in) are stubbed as empty modules: its motor buses use none of them.

Run (motorwire built, Python with lerobot 0.4.4 --no-deps, pyserial,
deepdiff, tqdm, numpy, feetech-servo-sdk and dynamixel-sdk):

    python3 lerobot_bus.py --motorwire path/to/motorwire --work DIR

It exits 1 on any failure, printing what LeRobot saw.
"""

import argparse
import importlib.abc
import importlib.machinery
import os
import subprocess
import sys
import time
import types

HEAVY = ("torch", "accelerate", "datasets", "torchvision", "huggingface_hub", "einops", "safetensors")


class Stub(types.ModuleType):
    """A module (and anything taken from it) that is nothing."""

    __path__ = []

    def __getattr__(self, name):
        if name.startswith("__") and name.endswith("__"):
            raise AttributeError(name)
        full = f"{self.__name__}.{name}"
        if full not in sys.modules:
            sys.modules[full] = Stub(full)
        return sys.modules[full]

    def __call__(self, *a, **k):
        return self

    def __or__(self, other):
        return self

    def __ror__(self, other):
        return self

    def __mro_entries__(self, bases):
        return (object,)


class Finder(importlib.abc.MetaPathFinder, importlib.abc.Loader):
    def find_spec(self, name, path, target=None):
        if name.split(".")[0] in HEAVY:
            return importlib.machinery.ModuleSpec(name, self, is_package=True)
        return None

    def create_module(self, spec):
        return Stub(spec.name)

    def exec_module(self, module):
        pass


sys.meta_path.insert(0, Finder())

from lerobot.motors import Motor, MotorCalibration, MotorNormMode  # noqa: E402
from lerobot.motors.dynamixel import DynamixelMotorsBus  # noqa: E402
from lerobot.motors.feetech import FeetechMotorsBus  # noqa: E402

JOINTS = ["shoulder_pan", "shoulder_lift", "elbow_flex", "wrist_flex", "wrist_roll", "gripper"]


def check(cond, what):
    if not cond:
        print(f"FAILED: {what}")
        sys.exit(1)
    print(f"ok: {what}")


def start_sim(motorwire, protocol, model, pty):
    p = subprocess.Popen(
        [motorwire, "sim", "servos", "--protocol", protocol, "--model", model, "--ids", "1,2,3,4,5,6", "--pty", pty],
        stderr=subprocess.PIPE,
        text=True,
    )
    line = p.stderr.readline()
    print(line.strip())
    check(os.path.islink(pty), f"motorwire sim servos linked its pseudo-terminal at {pty}")
    return p


def arm(bus_class, pty, model):
    motors = {name: Motor(i + 1, model, MotorNormMode.RANGE_M100_100) for i, name in enumerate(JOINTS)}
    motors["gripper"] = Motor(6, model, MotorNormMode.RANGE_0_100)
    return bus_class(port=pty, motors=motors)


def exercise(bus, model_number, half_turn):
    bus.connect()
    check(bus.is_connected, "connect(): the handshake found every motor, its model and firmware")
    found = bus.broadcast_ping()
    check(found == {i: model_number for i in range(1, 7)}, f"broadcast_ping() found ids 1 to 6, model {model_number}: {found}")
    bus.disable_torque()
    bus.configure_motors()
    before = bus.sync_read("Present_Position", normalize=False)
    offsets = bus.set_half_turn_homings()
    after = bus.sync_read("Present_Position", normalize=False)
    check(all(v == half_turn for v in after.values()), f"set_half_turn_homings(): every motor reads {half_turn} ({before} -> {after}, offsets {offsets})")
    calibration = {
        name: MotorCalibration(id=m.id, drive_mode=0, homing_offset=offsets[name], range_min=half_turn - 1000, range_max=half_turn + 1000)
        for name, m in bus.motors.items()
    }
    bus.write_calibration(calibration)
    check(bus.read_calibration() == calibration, "write_calibration() then read_calibration(): the same")
    bus.enable_torque()
    goals = {name: (50.0 if name != "gripper" else 25.0) for name in JOINTS}
    bus.sync_write("Goal_Position", goals)
    time.sleep(0.05)
    moving = bus.sync_read("Present_Position")
    check(any(abs(moving[n] - goals[n]) > 1.0 for n in JOINTS), f"sync_read() while moving: not there yet ({moving})")
    deadline = time.time() + 5.0
    while time.time() < deadline:
        arrived = bus.sync_read("Present_Position")
        if all(abs(arrived[n] - goals[n]) < 0.2 for n in JOINTS):
            break
        time.sleep(0.1)
    check(all(abs(arrived[n] - goals[n]) < 0.2 for n in JOINTS), f"sync_read() once arrived: at the goals ({arrived})")
    raw = bus.sync_read("Present_Position", normalize=False)
    check(raw["shoulder_pan"] == half_turn + 500, f"raw present position at the goal: {raw['shoulder_pan']}")
    for name in ("Present_Velocity", "Present_Temperature"):
        v = bus.read(name, "elbow_flex", normalize=False)
        check(isinstance(v, int), f"read({name}) = {v}")
    bus.disconnect()
    check(not bus.is_connected, "disconnect(): torque off, port closed")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--motorwire", required=True)
    ap.add_argument("--work", required=True)
    a = ap.parse_args()
    os.makedirs(a.work, exist_ok=True)
    for bus_class, protocol, model, number, half in (
        (FeetechMotorsBus, "scs0", "sts3215", 777, 2047),
        (DynamixelMotorsBus, "dxl2", "xl330-m288", 1200, 2047),
    ):
        pty = os.path.join(a.work, f"{model}.pty")
        sim = start_sim(a.motorwire, protocol, model, pty)
        try:
            print(f"--- LeRobot's {bus_class.__name__} on six simulated {model}")
            exercise(arm(bus_class, pty, model), number, half)
        finally:
            sim.terminate()
            sim.wait(timeout=5)
    print("LeRobot's motor buses ran against motorwire sim servos")


if __name__ == "__main__":
    main()
