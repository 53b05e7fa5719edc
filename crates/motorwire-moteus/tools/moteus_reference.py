#!/usr/bin/env python3
"""Differential test of `motorwire moteus encode|decode` against mjbots' Python
library `moteus` (written against moteus 1.1.1).

What it proves, on seeded random cases:

- encode: for each call line (`{"command":"position","id":1,"position":0.5,
  "query":true,...}`: a `Controller.make_*` call without `make_`, its keyword
  arguments by the library's names, `null` for NaN, optional `source`,
  `can_prefix`, `query_override` and the controller's `query_resolution`,
  `position_resolution`, `current_resolution`, `zero_velocity_resolution`),
  motorwire prints the same `{"can_id": N, "data": "hex"}` as the library:
  `data` is the library's `Command.data` byte for byte, `can_id` the
  arbitration id the library's transport builds for it
  (`Transport._command_to_frame`). The calls are drawn from the library's
  own signatures (`inspect.signature` of each `Controller.make_*`): every
  keyword it takes is drawn, with the types Python passes (`query` and
  `ignore_position_bounds` as true/false, numbers as ints and floats, NaN
  as null, `query_override` as an object or null for None). A keyword, or
  an attribute of a resolution class, that this script cannot draw values
  for stops it at once (exit 1, naming it), before anything is generated.
- decode: for each reply frame (`{"can_id": N, "data": "hex"}`), motorwire
  prints the same `{"id", "values", "errors"}` as the library reads it:
  `id` from `protocol.parse_message`, `values` the RESPONSE registers of
  `protocol.parse_registers` in the library's dict order, named by
  `moteus.Register` and scaled by `protocol.scale_register`, `errors` its
  error subframes. Values compare exactly: an int must be an int, a float
  a float with the same bits (so -0.0 is not 0.0); NaN is `null`,
  infinities are "inf" / "-inf".

Where the library raises (e.g. `struct.pack` of a value beyond f32's range,
`int(NaN)` for an integer register sent as an f32 NaN), the expected answer
is a refusal, and motorwire's `{"error": ..., "line": N}` for that line
counts as "both refused". One refusal is not the library's but its
transports': the library builds command frames longer than CAN-FD's 64
bytes without complaint, which no transport can send; such a call is
expected to be refused and is counted apart in the summary.

Nothing is hidden: every mismatch counts, and the summary groups the
mismatches by cause (for encode: command, field, resolution and the class of
the value; for decode: register, resolution and the kind of the wire value),
so that a whole class where the two differ (f32 against f64 arithmetic, say)
shows as one line with its count.

Run (the binary built beforehand; Python with `moteus` installed):

    python3 moteus_reference.py --motorwire path/to/motorwire --seed 1 \\
        --calls 10000 --replies 10000 [--show 10]

It exits 1 on any mismatch, when motorwire prints a different number of
lines than it was given, or when the library has a keyword the generator
does not know; 0 otherwise. To check the generator alone (no
motorwire needed), write the cases with the library's answers as JSON lines
`{"input": ..., "expected": ...}` and exit:

    python3 moteus_reference.py --seed 1 --calls 5000 --replies 5000 \\
        --dump-calls calls.jsonl --dump-replies replies.jsonl

Only the standard library and `moteus` are used.
"""

import argparse
import collections
import inspect
import json
import math
import random
import struct
import subprocess
import sys
from decimal import Decimal

import moteus
from moteus import multiplex as mp
from moteus import protocol
from moteus.moteus import (Controller, CurrentResolution, PositionResolution,
                           QueryResolution, ZeroVelocityResolution)
from moteus.transport import Transport
from moteus.transport_device import Frame

# --------------------------------------------------------------------------
# The library's names and constants.

RESOLUTIONS = {
    "int8": mp.INT8,
    "int16": mp.INT16,
    "int32": mp.INT32,
    "f32": mp.F32,
    "ignore": mp.IGNORE,
}
RES_NAME = {v: k for k, v in RESOLUTIONS.items()}
INT_TYPES = (mp.INT8, mp.INT16, mp.INT32)
INT_MAX = {mp.INT8: 127, mp.INT16: 32767, mp.INT32: 2147483647}
F32_MAX = struct.unpack("<f", bytes.fromhex("ffff7f7f"))[0]

# The scales of protocol.Writer's write_* per integer resolution (int8,
# int16, int32), as decimal text so that values on the grid can be written
# exactly (0.29 is 2900 steps of position at int16). They only aim the
# generated values: every expected answer comes from the library itself.
FAMILIES = {
    "position": ("0.01", "0.0001", "0.00001"),
    "velocity": ("0.1", "0.00025", "0.00001"),
    "accel": ("0.05", "0.001", "0.00001"),
    "torque": ("0.5", "0.01", "0.001"),
    "voltage": ("0.5", "0.1", "0.001"),
    "time": ("0.01", "0.001", "0.000001"),
    "current": ("1.0", "0.1", "0.001"),
    # write_pwm: 1/127, 1/32767, 1/2147483647 (not decimal).
    "pwm": None,
}
PWM_STEPS = (127.0, 32767.0, 2147483647.0)

# Each command's value arguments: (argument, attribute of the resolution
# object, scale family, register it is written to). "int" is write_int (sent
# as int(value); drawn as a bool too, as ignore_position_bounds=True is
# written), "raw" a plain f32 (set_output's position), "ignored" an argument
# the library takes and never sends (no attribute, no register). `query`
# and `query_override` are every command's (see KEYWORD_KINDS).
POSITION_ARGS = [
    ("position", "position", "position", 0x020),
    ("velocity", "velocity", "velocity", 0x021),
    ("feedforward_torque", "feedforward_torque", "torque", 0x022),
    ("kp_scale", "kp_scale", "pwm", 0x023),
    ("kd_scale", "kd_scale", "pwm", 0x024),
    ("maximum_torque", "maximum_torque", "torque", 0x025),
    ("stop_position", "stop_position", "position", 0x026),
    ("watchdog_timeout", "watchdog_timeout", "time", 0x027),
    ("velocity_limit", "velocity_limit", "velocity", 0x028),
    ("accel_limit", "accel_limit", "accel", 0x029),
    ("fixed_voltage_override", "fixed_voltage_override", "voltage", 0x02a),
    ("ilimit_scale", "ilimit_scale", "pwm", 0x02b),
    ("fixed_current_override", "fixed_current_override", "current", 0x02c),
    ("ignore_position_bounds", "ignore_position_bounds", "int", 0x02d),
]
# stay_within takes the position resolutions (both bounds at `position`'s).
# Its stop_position the library accepts and ignores (1.1.1 writes no
# register for it): drawn like a position, beyond f32's range too.
STAY_WITHIN_ARGS = [
    ("lower_bound", "position", "position", 0x040),
    ("upper_bound", "position", "position", 0x041),
    ("feedforward_torque", "feedforward_torque", "torque", 0x042),
    ("kp_scale", "kp_scale", "pwm", 0x043),
    ("kd_scale", "kd_scale", "pwm", 0x044),
    ("maximum_torque", "maximum_torque", "torque", 0x045),
    ("stop_position", None, "ignored", None),
    ("watchdog_timeout", "watchdog_timeout", "time", 0x046),
    ("ilimit_scale", "ilimit_scale", "pwm", 0x047),
    ("ignore_position_bounds", "ignore_position_bounds", "int", 0x048),
]
# command -> (its resolution object, its arguments)
COMMANDS = {
    "position": ("position_resolution", POSITION_ARGS),
    "stop": (None, []),
    "brake": (None, []),
    "query": (None, []),
    # Q first on the wire (COMMAND_Q_CURRENT is 0x01c).
    "current": ("current_resolution", [
        ("q_A", "q_A", "current", 0x01c),
        ("d_A", "d_A", "current", 0x01d),
    ]),
    "stay_within": ("position_resolution", STAY_WITHIN_ARGS),
    "zero_velocity": ("zero_velocity_resolution", [("kd_scale", "kd_scale", "pwm", 0x024)]),
    "set_output_nearest": (None, [("position", None, "raw", 0x130)]),
    "set_output_exact": (None, [("position", None, "raw", 0x131)]),
}
COMMAND_NAMES = list(COMMANDS)
# Arguments every generated call of the command carries (the library has no
# "not sent" for set_output's position: absent is its default 0.0; current's
# d_A and q_A are required arguments).
ALWAYS_SENT = {"current", "set_output_nearest", "set_output_exact"}

# QueryResolution's attributes: registers 0x000..0x007, 0x00a..0x00f,
# 0x05e, 0x05f, 0x072..0x075; rezero_state is the older name of 0x00c
# (home_state), the library merging the two. Its `_extra` (a dict of
# further registers) is not drawn.
QUERY_ATTRS = [
    "mode", "position", "velocity", "torque", "q_current", "d_current",
    "abs_position", "power", "motor_temperature", "trajectory_complete",
    "rezero_state", "home_state", "voltage", "temperature", "fault", "aux1_gpio",
    "aux2_gpio", "aux1_pwm_input_period_us", "aux1_pwm_input_duty_cycle",
    "aux2_pwm_input_period_us", "aux2_pwm_input_duty_cycle",
]

# Resolution object member -> (the library's class, its attributes).
RES_OBJECTS = {
    "query_resolution": (QueryResolution, QUERY_ATTRS),
    "position_resolution": (PositionResolution, [a[0] for a in POSITION_ARGS]),
    "current_resolution": (CurrentResolution, ["d_A", "q_A"]),
    "zero_velocity_resolution": (ZeroVelocityResolution, ["kd_scale"]),
}

# The keywords every make_* may take besides its value arguments, and what
# is drawn for them.
KEYWORD_KINDS = {
    "query": "true or false (absent: the default False)",
    "query_override": "a QueryResolution as an object, or null for None",
}


def expected_default(command, keyword):
    """The default the generator assumes for a keyword (absent from a line
    means this default): a changed default changes what absence means."""
    if keyword == "query":
        return False
    if command in ("set_output_nearest", "set_output_exact") and keyword == "position":
        return 0.0
    if command == "current" and keyword in ("d_A", "q_A"):
        return inspect.Parameter.empty  # required
    return None


def drawn_keywords(command):
    """The keywords the generator draws for make_<command>, in its order."""
    names = [a[0] for a in COMMANDS[command][1]]
    if command != "query":
        names.append("query")
    return names + ["query_override"]


def signature_problems():
    """What the library takes that the generator cannot draw (or draws and
    the library no longer takes): a list of texts, empty when none."""
    problems = []
    for command in COMMAND_NAMES:
        method = "Controller.make_%s" % command
        try:
            sig = inspect.signature(getattr(Controller, "make_" + command))
        except (AttributeError, TypeError, ValueError) as e:
            problems.append("%s: no signature (%s)" % (method, e))
            continue
        known = drawn_keywords(command)
        taken = []
        for p in sig.parameters.values():
            if p.name == "self":
                continue
            if p.kind == p.VAR_POSITIONAL:
                continue  # set_output's *args: the library refuses any
            if p.kind in (p.VAR_KEYWORD, p.POSITIONAL_ONLY):
                problems.append("%s takes %s (%s), which a JSON line cannot name" % (
                    method, p.name, p.kind.description))
                continue
            taken.append(p.name)
            if p.name not in known:
                problems.append(
                    "%s takes keyword %r (default %r), which the generator cannot draw"
                    " values for: teach it (and motorwire) this keyword" % (
                        method, p.name, p.default))
            elif p.default != expected_default(command, p.name):
                problems.append("%s: keyword %r defaults to %r, the generator assumes %r" % (
                    method, p.name, p.default, expected_default(command, p.name)))
        for name in known:
            if name not in taken:
                problems.append("the generator draws keyword %r, which %s does not take" % (
                    name, method))
    for key, (cls, attrs) in RES_OBJECTS.items():
        public = [a for a in vars(cls) if not a.startswith("_")]
        for a in public:
            if a not in attrs:
                problems.append("%s has attribute %r (%s's), which the generator cannot draw" % (
                    cls.__name__, a, key))
        for a in attrs:
            if a not in public:
                problems.append("the generator draws %s.%s, which the library has not" % (
                    cls.__name__, a))
    return problems


# A transport with no devices: only its frame builder is used, so that the
# CAN id is the one the library's transport would send.
TRANSPORT = Transport([])

REGISTER_VALUES = set(int(r) for r in protocol.Register)


def f32(x):
    """x rounded to the nearest f32 (as a Python float)."""
    return struct.unpack("<f", struct.pack("<f", x))[0]


def weighted(rng, table):
    """One key of `table` (a list of (key, weight)), by weight."""
    keys = [k for k, _ in table]
    weights = [w for _, w in table]
    return rng.choices(keys, weights=weights)[0]


def counts_text(counter, by_count=False):
    """A Counter as "a 1, b 2", by key or by count."""
    items = counter.most_common() if by_count else sorted(counter.items())
    return ", ".join("%s %d" % kv for kv in items)


# --------------------------------------------------------------------------
# Calls: generation.

RES_WEIGHTS = [("int8", 25), ("int16", 25), ("int32", 23), ("f32", 15), ("ignore", 12)]
# A query asks for fewer registers than a command sends (so that most
# command + query frames fit in 64 bytes).
QUERY_RES_WEIGHTS = [("int8", 20), ("int16", 16), ("int32", 10), ("f32", 12), ("ignore", 42)]


def random_resolutions(rng, key):
    """A resolution object's members: a random subset of its attributes."""
    attrs = RES_OBJECTS[key][1]
    table = QUERY_RES_WEIGHTS if key == "query_resolution" else RES_WEIGHTS
    density = rng.choice((0.3, 0.6, 0.9, 1.0))
    return {a: weighted(rng, table) for a in attrs if rng.random() < density}


def grid_value(family, index, k):
    """k steps of the family's scale at resolution `index` (0..2)."""
    if family == "pwm":
        return k / PWM_STEPS[index]
    return float(Decimal(k) * Decimal(FAMILIES[family][index]))


def half_grid_value(family, index, k):
    """Half way between step k and k + 1 (where truncation decides)."""
    if family == "pwm":
        return (k + 0.5) / PWM_STEPS[index]
    return float(Decimal(2 * k + 1) * Decimal(FAMILIES[family][index]) / 2)


SCALED_CLASSES = [
    ("nan", 5), ("zero", 4), ("grid", 18), ("half-grid", 6), ("saturation-edge", 10),
    ("saturating", 7), ("off-grid", 13), ("f32-exact", 12), ("tiny", 5), ("large", 7),
    ("f32-max-as-text", 1), ("beyond-f32", 3),
]
RAW_CLASSES = [
    ("nan", 6), ("zero", 6), ("decimal", 16), ("off-grid", 18), ("f32-exact", 20),
    ("tiny", 8), ("large", 10), ("f32-max-as-text", 2), ("beyond-f32", 4),
]
# The classes of magnitudes over f32's largest, drawn only in some calls (the
# library refuses a whole call for one such value sent as an f32).
WIDE_CLASSES = ("f32-max-as-text", "beyond-f32")
INTEGRAL_CLASSES = [
    ("bool", 30), ("small-int", 40), ("non-integer", 25), ("integral-float", 10), ("saturating-int", 20),
    ("large-non-integer", 5), ("nan", 3),
]


def maybe_int(rng, value):
    """Sometimes write an integral value as a JSON integer."""
    if value != 0 and value.is_integer() and abs(value) < 2**53 and rng.random() < 0.3:
        return int(value)
    return value


def tiny(rng):
    """A tiny magnitude (f32 subnormals, and below)."""
    sign = rng.choice((-1.0, 1.0))
    return sign * rng.choice((5e-324, 1e-45, 1.401298464324817e-45, 1e-40,
                              10 ** rng.uniform(-46, -8)))


def large(rng):
    """A large magnitude within f32's range."""
    sign = rng.choice((-1.0, 1.0))
    return sign * rng.choice((1e6, 1e30, 1e38, F32_MAX, 10 ** rng.uniform(5, 38)))


def beyond_f32(rng):
    """A magnitude beyond f32's range (not infinite: JSON has no infinity)."""
    sign = rng.choice((-1.0, 1.0))
    return sign * rng.choice((1e39, 3.5e38, 1e100, 1.7976931348623157e308,
                              10 ** rng.uniform(39, 308)))


def draw_class(rng, table, wide):
    """A value class from `table`; over f32's range only if `wide`."""
    return weighted(rng, [(c, w) for c, w in table if wide or c not in WIDE_CLASSES])


def gen_value(rng, family, res, wide):
    """A JSON value for an argument of `family` sent at `res`, and its class."""
    if family == "int":
        return gen_integral(rng)
    if family == "ignored":
        # Not sent: any number the caller might pass, NaN and over f32 too.
        return gen_value(rng, "position", mp.IGNORE, wide)
    if family == "raw":
        return gen_raw_position(rng, wide)
    cls = draw_class(rng, SCALED_CLASSES, wide)
    # The resolution whose grid the value aims at: its own, or for f32 and
    # ignore any of the three.
    int_res = res if res in INT_TYPES else rng.choice(INT_TYPES)
    index = INT_TYPES.index(int_res)
    m = INT_MAX[int_res]
    step = grid_value(family, index, 1)
    if cls == "nan":
        return None, cls
    if cls == "zero":
        return rng.choice((0, 0.0, -0.0)), cls
    if cls == "grid":
        k = rng.choice((rng.randint(-1000, 1000), rng.randint(-m, m),
                        rng.choice((1, -1)) * (m - rng.randint(0, 50))))
        return maybe_int(rng, grid_value(family, index, k)), cls
    if cls == "half-grid":
        k = rng.choice((rng.randint(-1000, 1000), rng.randint(-m, m - 1)))
        return half_grid_value(family, index, k), cls
    if cls == "saturation-edge":
        k = rng.choice((m, m + 1, -m, -m - 1, m - 1, -m + 1, -m - 2, m + 2))
        return maybe_int(rng, grid_value(family, index, k)), cls
    if cls == "saturating":
        sign = rng.choice((-1, 1))
        if rng.random() < 0.5:
            k = sign * (m + rng.randint(2, 10 * m))
            return maybe_int(rng, grid_value(family, index, k)), cls
        return sign * m * step * 10 ** rng.uniform(0.001, 4), cls
    if cls == "off-grid":
        span = m * step * rng.choice((0.001, 0.1, 1.0))
        return rng.uniform(-span, span), cls
    if cls == "f32-exact":
        if rng.random() < 0.7:
            span = m * step * rng.choice((0.001, 0.1, 1.0, 2.0))
            return f32(rng.uniform(-span, span)), cls
        return random_f32(rng, -30, 30), cls
    if cls == "tiny":
        return tiny(rng), cls
    if cls == "large":
        return large(rng), cls
    if cls == "f32-max-as-text":
        # How f32's largest value is usually written: just over it as an f64,
        # rounding down to it as an f32.
        return rng.choice((3.4028235e38, -3.4028235e38)), cls
    return beyond_f32(rng), cls


def random_f32(rng, lo_exp, hi_exp):
    """A random finite f32 with its binary exponent in [lo_exp, hi_exp]."""
    sign = rng.getrandbits(1) << 31
    exponent = rng.randint(lo_exp, hi_exp) + 127
    mantissa = rng.getrandbits(23)
    return struct.unpack("<f", struct.pack("<I", sign | (exponent << 23) | mantissa))[0]


def gen_raw_position(rng, wide):
    """set_output's position: sent as an f32 as it is."""
    cls = draw_class(rng, RAW_CLASSES, wide)
    if cls == "nan":
        return None, cls
    if cls == "zero":
        return rng.choice((0, 0.0, -0.0)), cls
    if cls == "decimal":
        return maybe_int(rng, round(rng.uniform(-100, 100), rng.randint(0, 4))), cls
    if cls == "off-grid":
        return rng.uniform(-1000, 1000) * rng.choice((1e-3, 1.0, 1e3)), cls
    if cls == "f32-exact":
        return random_f32(rng, -40, 40), cls
    if cls == "tiny":
        return tiny(rng), cls
    if cls == "large":
        return large(rng), cls
    if cls == "f32-max-as-text":
        return rng.choice((3.4028235e38, -3.4028235e38)), cls
    return beyond_f32(rng), cls


def gen_integral(rng):
    """ignore_position_bounds: the library sends int(value); finite only.
    A flag: most often passed as True or False."""
    cls = weighted(rng, INTEGRAL_CLASSES)
    if cls == "bool":
        return rng.choice((True, False)), cls
    if cls == "nan":
        return None, cls  # int(NaN): the library raises
    if cls == "small-int":
        return rng.randint(-3, 3), cls
    if cls == "non-integer":
        return rng.choice((1.7, -1.7, 0.5, -0.5, 0.999, -0.999, 2.3,
                           round(rng.uniform(-10, 10), 3))), cls
    if cls == "integral-float":
        return rng.choice((1.0, 0.0, -0.0, 3.0, -2.0)), cls
    if cls == "saturating-int":
        return rng.choice((127, 128, -127, -128, -129, 200, -300, 32767, 32768,
                           -32767, -32768, -32769, 100000, -100000, 16777215,
                           16777217, -16777217, 2147483647, 2147483648, -2147483648,
                           -2147483649, 1e6, 3e9, -1e12, 1e30)), cls
    return rng.choice((40000.5, -40000.5, 128.9, -128.9, 1234567.25)), cls


def gen_call(rng):
    """One random call line (a dict) and what was chosen for each argument:
    {argument: (resolution name, value class)}."""
    command = rng.choice(COMMAND_NAMES)
    res_key, args = COMMANDS[command]
    line = {"command": command, "id": rng.choice((1, 127, rng.randint(1, 127)))}
    if rng.random() < 0.5:
        line["source"] = rng.choice((0, 127, rng.randint(0, 127)))
    if rng.random() < 0.3:
        line["can_prefix"] = rng.choice((0, 0x1fff, rng.randint(0, 0x1fff)))
    for key in RES_OBJECTS:
        if key == res_key:
            p = 0.9
        elif key == "query_resolution":
            p = 0.35
        else:
            p = 0.08  # a resolution object the command does not use
        if rng.random() < p:
            line[key] = random_resolutions(rng, key)
    meta = {}
    density = rng.choice((0.15, 0.35, 0.6, 0.9))
    wide = rng.random() < 0.3
    for arg, attr, family, _reg in args:
        if command not in ALWAYS_SENT and rng.random() >= density:
            continue
        if family == "ignored":
            res = mp.IGNORE  # taken, never sent
        elif attr is None:
            res = mp.F32  # set_output: always an f32
        elif attr in line.get(res_key, {}):
            res = RESOLUTIONS[line[res_key][attr]]
        else:
            res = getattr(RES_OBJECTS[res_key][0], attr)  # the library's default
        value, cls = gen_value(rng, family, res, wide)
        line[arg] = value
        meta[arg] = (RES_NAME[res], cls)
    if command != "query" and rng.random() < 0.85:
        line["query"] = rng.random() < 0.5
    r = rng.random()
    if r < 0.25:
        line["query_override"] = random_resolutions(rng, "query_resolution")
    elif r < 0.3:
        line["query_override"] = None  # the default, passed explicitly
    return line, meta


# --------------------------------------------------------------------------
# Calls: the library's answer.

class Refused:
    """An expected refusal: the library raised (or built a frame no
    transport can send)."""

    def __init__(self, reason, over_64=False):
        self.reason = reason
        self.over_64 = over_64

    def to_json(self):
        return {"error": self.reason}

    def group(self):
        """The reason without its details, for the summary."""
        return "frame over 64 bytes" if self.over_64 else self.reason.split(":")[0]


def resolution_object(key, members):
    """A fresh instance of the library's resolution class with `members` set
    on the instance (the class attributes stay untouched)."""
    obj = RES_OBJECTS[key][0]()
    for attr, name in members.items():
        setattr(obj, attr, RESOLUTIONS[name])
    return obj


def library_encode(obj):
    """The library's frame for call `obj` (parsed from its JSON line), as
    {"can_id", "data"}, or a Refused."""
    try:
        command = obj["command"]
        resolutions = {key: resolution_object(key, obj.get(key, {})) for key in RES_OBJECTS}
        controller = Controller(
            id=obj["id"],
            source_can_id=obj.get("source", 0),
            can_prefix=obj.get("can_prefix", 0),
            **resolutions)
        kwargs = {}
        for name in drawn_keywords(command):
            if name not in obj:
                continue  # the library's default
            v = obj[name]
            if name == "query_override":
                kwargs[name] = None if v is None else resolution_object("query_resolution", v)
            elif name == "query":
                kwargs[name] = v
            else:
                kwargs[name] = math.nan if v is None else v
        cmd = getattr(controller, "make_" + command)(**kwargs)
        frame = TRANSPORT._command_to_frame(cmd)
        data = bytes(cmd.data)
    except Exception as e:  # the library refuses the call
        return Refused("library raised %s: %s" % (type(e).__name__, e))
    if len(data) > 64:
        return Refused("the library builds a %d-byte frame, over CAN-FD's 64"
                       " (no transport sends it)" % len(data), over_64=True)
    return {"can_id": frame.arbitration_id, "data": data.hex()}


# --------------------------------------------------------------------------
# Replies: generation.

QUERY_REGS = list(range(0x000, 0x010)) + [0x05e, 0x05f, 0x072, 0x073, 0x074, 0x075]
COMMAND_REGS = list(range(0x020, 0x02e)) + list(range(0x040, 0x049))
OTHER_REGS = (list(range(0x010, 0x01f)) + list(range(0x030, 0x03e)) + list(range(0x050, 0x080))
              + [0x100, 0x101, 0x102, 0x110, 0x120, 0x121, 0x122, 0x130, 0x131, 0x132, 0x133,
                 0x140, 0x141] + list(range(0x150, 0x159)))
UNKNOWN_REGS = [0x080, 0x0ff, 0x103, 0x1ff, 0x200, 0x3ff, 0x7ff, 0x3fff, 0x4000]
REG_FAMILIES = [("query", QUERY_REGS, 50), ("command", COMMAND_REGS, 20),
                ("other known", OTHER_REGS, 20), ("unknown", UNKNOWN_REGS, 10)]
CAN_FD_SIZES = (0, 1, 2, 3, 4, 5, 6, 7, 8, 12, 16, 20, 24, 32, 48, 64)


def register_family(reg):
    """Which family a register is counted in."""
    if reg not in REGISTER_VALUES:
        return "unknown"
    if reg in QUERY_REGS:
        return "query"
    if reg in COMMAND_REGS:
        return "command"
    return "other known"


def varuint(n):
    """n as the protocol's varuint (7 bits a byte, low first)."""
    out = bytearray()
    while True:
        b = n & 0x7f
        n >>= 7
        out.append(b | (0x80 if n else 0))
        if not n:
            return bytes(out)


def pick_register(rng):
    """A register, most often one a query reads."""
    family = rng.choices(REG_FAMILIES, weights=[w for _, _, w in REG_FAMILIES])[0]
    return rng.choice(family[1])


INT_KINDS = [("random", 30), ("nan-sentinel", 12), ("max", 8), ("min+1", 8), ("zero", 10),
             ("small", 32)]
F32_KINDS = [("nan", 6), ("inf", 4), ("zero", 6), ("integral", 20), ("fraction", 20),
             ("f32-max", 3), ("subnormal", 4), ("random-bits", 20), ("huge", 5)]
NAN_BITS = (0x7fc00000, 0xffc00000, 0x7f800001, 0x7fffffff, 0xffffffff)


def gen_wire_value(rng, res):
    """One value of a REPLY block at `res`: its bytes and its kind."""
    if res in INT_TYPES:
        kind = weighted(rng, INT_KINDS)
        m = INT_MAX[res]
        v = {"random": rng.randint(-m - 1, m), "nan-sentinel": -m - 1, "max": m,
             "min+1": -m, "zero": 0, "small": rng.randint(-5, 20)}[kind]
        return mp.TYPES[res].pack(v), kind
    kind = weighted(rng, F32_KINDS)
    if kind == "nan":
        bits = rng.choice(NAN_BITS)
    elif kind == "inf":
        bits = rng.choice((0x7f800000, 0xff800000))
    elif kind == "zero":
        bits = rng.choice((0, 0x80000000))
    elif kind == "f32-max":
        bits = rng.choice((0x7f7fffff, 0xff7fffff))
    elif kind == "subnormal":
        bits = rng.randint(1, 0x7fffff) | (rng.getrandbits(1) << 31)
    elif kind == "random-bits":
        bits = rng.getrandbits(32)
        while (bits >> 23) & 0xff == 0xff:
            bits = rng.getrandbits(32)
    else:
        v = {"integral": float(rng.randint(-20, 300)),
             "fraction": rng.uniform(-100, 100),
             "huge": rng.choice((-1, 1)) * 10 ** rng.uniform(19, 38)}[kind]
        return struct.pack("<f", v), kind
    return struct.pack("<I", bits), kind


def gen_block(rng, last_register):
    """One subframe of a reply: its bytes, the features it shows and its
    first register (None for an error subframe)."""
    if rng.random() < 0.12:
        code = rng.choice((rng.randint(0, 10), rng.randint(0, 127), rng.randint(128, 400), 0x3fff))
        op = rng.choice((mp.WRITE_ERROR, mp.READ_ERROR))
        return bytes([op]) + varuint(pick_register(rng)) + varuint(code), {"error subframe"}, None
    if last_register is not None and rng.random() < 0.1:
        register = last_register  # the same register again: the last value wins
    else:
        register = pick_register(rng)
    res = weighted(rng, [(mp.INT8, 25), (mp.INT16, 25), (mp.INT32, 20), (mp.F32, 30)])
    if rng.random() < 0.75:
        count = rng.randint(1, 3)
        head = bytes([mp.REPLY_BASE | (res << 2) | count])
        features = {"short-form count"}
    else:
        count = rng.randint(1, 6)
        head = bytes([mp.REPLY_BASE | (res << 2)]) + varuint(count)
        features = {"long-form count"}
    features.add(RES_NAME[res])
    body = bytearray(varuint(register))
    for _ in range(count):
        body += gen_wire_value(rng, res)[0]
    return head + bytes(body), features, register


def gen_reply(rng):
    """One random reply line (a dict) and its features."""
    data = bytearray()
    features = set()
    last_register = None
    for _ in range(rng.randint(1, 6)):
        for _attempt in range(4):
            chunk, feats, register = gen_block(rng, last_register)
            nop = b""
            if data and rng.random() < 0.08:
                nop = b"\x50" * rng.randint(1, 2)
            if len(data) + len(nop) + len(chunk) <= 64:
                break
        else:
            break
        if nop:
            features.add("NOP between")
        data += nop + chunk
        features |= feats
        if register is not None:
            last_register = register
    if rng.random() < 0.35:
        # Padded to the next CAN-FD length, as a transport pads.
        size = min(s for s in CAN_FD_SIZES if s >= len(data))
        if size > len(data):
            features.add("DLC padding")
            data += b"\x50" * (size - len(data))
    can_id = (rng.randint(1, 127) << 8) | rng.choice((0, 127, rng.randint(0, 127)))
    if rng.random() < 0.5:
        can_id |= 0x8000
    if rng.random() < 0.3:
        can_id |= rng.choice((0x1fff, rng.randint(0, 0x1fff))) << 16
    return {"can_id": can_id, "data": data.hex()}, features


# --------------------------------------------------------------------------
# Replies: the library's answer.

def json_value(v):
    """A scaled value as the contract writes it."""
    if isinstance(v, bool):
        raise TypeError("unexpected bool %r" % v)
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        if math.isnan(v):
            return None
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return v
    raise TypeError("unexpected value %r" % (v,))


def register_name(reg):
    """moteus.Register(reg).name, or None for a number it does not name."""
    try:
        return protocol.Register(reg).name
    except ValueError:
        return None


def library_decode(obj):
    """The library's reading of reply `obj`, or a Refused."""
    data = bytes.fromhex(obj["data"])
    try:
        message = protocol.parse_message(Frame(arbitration_id=obj["can_id"], data=data))
        parsed = protocol.parse_registers(data)
        values = [{"register": reg, "name": register_name(reg), "value": json_value(v)}
                  for reg, v in parsed.response.items()]
        # An integer register holding an f32 beyond 64 bits (1e30 as the
        # mode): the library gives a 31-digit integer, motorwire refuses the
        # reply (no register holds such a number; the frame is broken).
        for v in values:
            if isinstance(v["value"], int) and abs(v["value"]) >= 2**63:
                return Refused("an integer register holds a float beyond 64 bits: %d" % v["value"])
        errors = [{"register": reg, "code": code} for reg, code in parsed.errors]
        return {"id": message.id, "values": values, "errors": errors}
    except Exception as e:
        return Refused("library raised %s: %s" % (type(e).__name__, e))


def response_subframes(data):
    """The last RESPONSE subframe of each register: {register: (res, raw)}."""
    out = {}
    for sub in mp.parse_frame(data):
        if isinstance(sub, mp.RegisterSubframe) and sub.type == mp.SubframeType.RESPONSE:
            out[sub.register] = (sub.resolution, sub.value)
    return out


def raw_kind(res, raw):
    """The kind of a wire value, for grouping mismatches."""
    if res in INT_TYPES:
        m = INT_MAX[res]
        if raw == -m - 1:
            return "nan-sentinel"
        if raw in (m, -m):
            return "extreme"
        return "zero" if raw == 0 else "other"
    if math.isnan(raw):
        return "nan"
    if math.isinf(raw):
        return "inf"
    if raw == 0:
        return "zero"
    if abs(raw) >= 2**63:
        return "beyond i64"
    if raw.is_integer():
        return "integral"
    return "fraction" if abs(raw) >= 1.1754943508222875e-38 else "subnormal"


# --------------------------------------------------------------------------
# Comparison.

def same(a, b):
    """Exact equality of two JSON values: types equal (an int is not a
    float), floats bit for bit."""
    if type(a) is not type(b):
        return False
    if isinstance(a, float):
        return struct.pack("<d", a) == struct.pack("<d", b)
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(same(a[k], b[k]) for k in a)
    if isinstance(a, list):
        return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
    return a == b


def is_refusal(actual):
    """Whether motorwire's answer is its {"error", "line"} refusal."""
    return isinstance(actual, dict) and "error" in actual


def shown(v):
    """An expected answer as printed with a mismatch."""
    return json.dumps(v.to_json() if isinstance(v, Refused) else v)


def register_subframes(data):
    """(type, register, resolution, value) of every register subframe."""
    return [(s.type.name, s.register, s.resolution, s.value)
            for s in mp.parse_frame(data) if isinstance(s, mp.RegisterSubframe)]


def same_raw(a, b):
    """Two wire values equal (any two NaN alike)."""
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return same(a, b)


# A mismatch of one value: counted by `row` (the argument, or the register)
# and resolution, and by `kind` (the value's class, or the wire value's kind)
# and resolution.
Cell = collections.namedtuple("Cell", "row res kind")


def explain_call(line, meta, expected, actual):
    """Why a call's answers differ: Cells and texts, for the summary."""
    command = line["command"]
    if isinstance(expected, Refused):
        return ["%s: the library refuses (%s), motorwire answers" % (command, expected.group())]
    if is_refusal(actual):
        message = str(actual["error"])
        arg = message.split(":")[0]
        if arg in meta and not message.startswith(command + ": "):
            res, cls = meta[arg]
            return [Cell("%s.%s" % (command, arg), res, cls + ", motorwire refuses")]
        return ["%s: motorwire refuses (%s)" % (command, message[:70])]
    if not isinstance(actual, dict) or set(actual) != {"can_id", "data"}:
        return ["%s: motorwire's answer is not {can_id, data}" % command]
    keys = []
    if not same(actual["can_id"], expected["can_id"]):
        keys.append("%s: can_id" % command)
    if actual["data"] != expected["data"]:
        try:
            got = register_subframes(bytes.fromhex(actual["data"]))
        except Exception:
            return keys + ["%s: motorwire's data does not parse" % command]
        want = register_subframes(bytes.fromhex(expected["data"]))
        layout_want = [s[:3] for s in want]
        layout_got = [s[:3] for s in got]
        if layout_want != layout_got:
            writes_differ = ([s for s in layout_want if s[0] == "WRITE"]
                             != [s for s in layout_got if s[0] == "WRITE"])
            keys.append("%s: %s layout (registers or resolutions sent)" % (
                command, "command" if writes_differ else "query"))
        else:
            reg_to_arg = {reg: arg for arg, _a, _f, reg in COMMANDS[command][1]}
            found = False
            for (_t, reg, res, v_want), (_t2, _r, _res, v_got) in zip(want, got):
                if same_raw(v_want, v_got):
                    continue
                found = True
                arg = reg_to_arg.get(reg)
                if arg in meta:
                    keys.append(Cell("%s.%s" % (command, arg), meta[arg][0], meta[arg][1]))
                else:
                    keys.append("%s: register 0x%03x at %s" % (command, reg, RES_NAME[res]))
            if not found:
                keys.append("%s: bytes differ (same values, e.g. NaN payload)" % command)
    return keys or ["%s: differs" % command]


def explain_reply(line, _features, expected, actual):
    """Why a reply's answers differ: Cells and texts, for the summary."""
    if isinstance(expected, Refused):
        return ["the library refuses (%s), motorwire answers" % expected.group()]
    if is_refusal(actual):
        return ["motorwire refuses (%s)" % str(actual["error"])[:70]]
    if not isinstance(actual, dict) or set(actual) != {"id", "values", "errors"}:
        return ["motorwire's answer is not {id, values, errors}"]
    keys = []
    if not same(actual["id"], expected["id"]):
        keys.append("id")
    if not same(actual["errors"], expected["errors"]):
        keys.append("error subframes")
    got = actual["values"]
    want = expected["values"]
    if (not isinstance(got, list) or len(got) != len(want)
            or any(not isinstance(g, dict) or g.get("register") != w["register"]
                   for g, w in zip(got, want))):
        keys.append("register list (which registers, or their order)")
        return keys
    wire = response_subframes(bytes.fromhex(line["data"]))
    for g, w in zip(got, want):
        reg = w["register"]
        if not same(g.get("name"), w["name"]):
            keys.append("name of register 0x%03x" % reg)
        if not same(g.get("value"), w["value"]):
            res, raw = wire[reg]
            kind = raw_kind(res, raw)
            if {type(g.get("value")), type(w["value"])} == {int, float}:
                kind += ", int vs float"
            keys.append(Cell("0x%03x %s" % (reg, w["name"] or "(unnamed)"), RES_NAME[res], kind))
        if set(g) != {"register", "name", "value"}:
            keys.append("members of a value")
    return keys or ["differs"]


def print_matrix(title, counts, columns, max_rows=40):
    """Prints counts[(row, column)] as a table, the largest rows first."""
    total = collections.Counter()
    for (r, _c), n in counts.items():
        total[r] += n
    rows = sorted(total, key=lambda r: (-total[r], r))
    print("  %-46s %s" % (title, " ".join("%6s" % c for c in columns)))
    for r in rows[:max_rows]:
        print("    %-44s %s" % (r, " ".join("%6d" % counts[(r, c)] for c in columns)))
    if len(rows) > max_rows:
        rest = rows[max_rows:]
        print("    (%d more rows, %d mismatched values)" % (len(rest), sum(total[r] for r in rest)))


# --------------------------------------------------------------------------
# Running motorwire.

def run_motorwire(path, subcommand, lines):
    """motorwire's output lines for `lines`, or None (with a message) when it
    could not be run."""
    try:
        done = subprocess.run([path, "moteus", subcommand], input="".join(t + "\n" for t in lines),
                              capture_output=True, text=True, timeout=600)
    except (OSError, subprocess.TimeoutExpired) as e:
        print("motorwire moteus %s: could not run: %s" % (subcommand, e))
        return None
    # motorwire exits 1 when it refused some line; that is compared line by line.
    if done.returncode not in (0, 1):
        print("motorwire moteus %s exited %d; stderr:\n%s" % (
            subcommand, done.returncode, done.stderr[-2000:]))
    return done.stdout.splitlines()


def row_order(kind):
    """The summary's rows: all first, then the commands in order, then the
    rest by name."""
    return (not kind.startswith("all "),
            COMMAND_NAMES.index(kind) if kind in COMMAND_NAMES else len(COMMAND_NAMES), kind)


def compare(what, cases, outputs, explain, kinds_of, show, row_title, kind_title):
    """Compares motorwire's outputs with the library's answers; prints the
    summary; returns True when everything agrees."""
    ok = True
    if len(outputs) != len(cases):
        print("%s: motorwire printed %d lines for %d inputs" % (what, len(outputs), len(cases)))
        ok = False
    table = {}
    causes = collections.Counter()
    both_refused = collections.Counter()
    shown_count = 0
    for case, out in zip(cases, outputs):
        text, obj, meta, expected = case
        try:
            actual = json.loads(out)
        except ValueError:
            actual = {"not json": out}
        if isinstance(expected, Refused) and is_refusal(actual):
            verdict = "both refused"
            both_refused[expected.group()] += 1
        elif not isinstance(expected, Refused) and same(actual, expected):
            verdict = "agree"
        else:
            verdict = "mismatch"
            for key in explain(obj, meta, expected, actual):
                causes[key] += 1
            if shown_count < show:
                shown_count += 1
                print("--- %s mismatch %d" % (what, shown_count))
                print("  input:     %s" % text)
                print("  library:   %s" % shown(expected))
                print("  motorwire: %s" % out)
        for kind in kinds_of(obj, meta, expected):
            row = table.setdefault(kind, collections.Counter())
            row["compared"] += 1
            row[verdict] += 1
    print()
    print("%s: %d compared" % (what, min(len(outputs), len(cases))))
    print("  %-28s %9s %9s %13s %9s" % ("", "compared", "agree", "both refused", "mismatch"))
    for kind in sorted(table, key=row_order):
        row = table[kind]
        print("  %-28s %9d %9d %13d %9d" % (kind, row["compared"], row["agree"],
                                            row["both refused"], row["mismatch"]))
    if both_refused:
        print("  both refused, by the library's reason:")
        for reason, n in both_refused.most_common():
            print("    %6d  %s" % (n, reason))
    if causes:
        ok = False
        cells = [k for k in causes if isinstance(k, Cell)]
        if cells:
            columns = [c for c in ("int8", "int16", "int32", "f32", "ignore")
                       if any(k.res == c for k in cells)]
            by_row = collections.Counter()
            by_kind = collections.Counter()
            for k in cells:
                by_row[(k.row, k.res)] += causes[k]
                by_kind[(k.kind, k.res)] += causes[k]
            print("  mismatched values (a line may count more than once):")
            print_matrix(row_title, by_row, columns)
            print_matrix(kind_title, by_kind, columns)
        texts = [k for k in causes if not isinstance(k, Cell)]
        if texts:
            print("  other mismatches:")
            for key in sorted(texts, key=lambda k: -causes[k]):
                print("    %6d  %s" % (causes[key], key))
    return ok


# --------------------------------------------------------------------------
# Coverage of the generator.

JSON_TYPES = ("absent", "bool", "int", "float", "null", "object")


def json_type(v):
    """A JSON value's type, as counted in the coverage."""
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "bool"
    if isinstance(v, int):
        return "int"
    if isinstance(v, float):
        return "float"
    return "object" if isinstance(v, dict) else type(v).__name__


def call_coverage(cases):
    """Prints what the generated calls cover."""
    commands = collections.Counter()
    per_arg = collections.defaultdict(collections.Counter)
    classes = collections.defaultdict(collections.Counter)
    flags = collections.Counter()
    refused = collections.Counter()
    by_type = collections.defaultdict(collections.Counter)
    for text, obj, meta, expected in cases:
        commands[obj["command"]] += 1
        for name in drawn_keywords(obj["command"]):
            by_type[(obj["command"], name)][json_type(obj[name]) if name in obj else "absent"] += 1
        for arg, (res, cls) in meta.items():
            per_arg[(obj["command"], arg)][res] += 1
            classes[cls][res] += 1
        for key in ("query_override", "query_resolution", "position_resolution",
                    "current_resolution", "zero_velocity_resolution", "source", "can_prefix"):
            if key in obj:
                flags[key] += 1
        if obj.get("query"):
            flags["query true"] += 1
        if isinstance(expected, Refused):
            refused[expected.group()] += 1
    print("calls generated: %d" % len(cases))
    print("  by command: " + counts_text(commands))
    print("  members: " + counts_text(flags))
    res_names = ["int8", "int16", "int32", "f32", "ignore"]
    print("  arguments by resolution  %s" % " ".join("%7s" % r for r in res_names))
    gaps = []
    for command in COMMAND_NAMES:
        for arg, attr, family, _r in COMMANDS[command][1]:
            row = per_arg[(command, arg)]
            print("    %-34s %s" % ("%s.%s" % (command, arg),
                                   " ".join("%7d" % row[r] for r in res_names)))
            if family == "ignored":
                expected_res = ["ignore"]
            else:
                expected_res = ["f32"] if attr is None else res_names
            gaps += ["%s.%s at %s" % (command, arg, r) for r in expected_res if not row[r]]
        if not commands[command]:
            gaps.append("command %s" % command)
    print("  keywords (make_*'s signature) by JSON type  %s" % " ".join(
        "%7s" % t for t in JSON_TYPES))
    for command in COMMAND_NAMES:
        for name in drawn_keywords(command):
            row = by_type[(command, name)]
            print("    %-41s %s" % ("%s.%s" % (command, name),
                                    " ".join("%7d" % row[t] for t in JSON_TYPES)))
            if commands[command] and all(not row[t] for t in JSON_TYPES if t != "absent"):
                gaps.append("keyword %s.%s never drawn" % (command, name))
    for command, name, t in [(c, "query_override", t) for c in COMMAND_NAMES
                             for t in ("object", "null")] + [
                                 ("position", "ignore_position_bounds", "bool"),
                                 ("stay_within", "ignore_position_bounds", "bool")] + [
                                 (c, "query", "bool") for c in COMMAND_NAMES if c != "query"]:
        if commands[command] and not by_type[(command, name)][t]:
            gaps.append("keyword %s.%s never %s" % (command, name, t))
    print("  value classes by resolution")
    for cls in sorted(classes):
        print("    %-34s %s" % (cls, " ".join("%7d" % classes[cls][r] for r in res_names)))
    if refused:
        print("  the library refuses: " + counts_text(refused, by_count=True))
    print("  coverage gaps: %s" % (", ".join(gaps) if gaps else "none"))


def reply_coverage(cases):
    """Prints what the generated replies cover."""
    families = collections.Counter()
    named = collections.Counter()
    kinds = collections.Counter()
    features = collections.Counter()
    refused = collections.Counter()
    lengths = []
    for text, obj, feats, expected in cases:
        data = bytes.fromhex(obj["data"])
        lengths.append(len(data))
        features.update(feats)
        for sub in mp.parse_frame(data):
            if isinstance(sub, mp.RegisterSubframe):
                families[register_family(sub.register)] += 1
                named["named" if register_name(sub.register) else "unnamed"] += 1
                res = sub.resolution
                kinds["%s %s" % (RES_NAME[res], raw_kind(res, sub.value))] += 1
        if isinstance(expected, Refused):
            refused[expected.group()] += 1
    print("replies generated: %d (%d to %d bytes)" % (
        len(cases), min(lengths or [0]), max(lengths or [0])))
    print("  register values by family: " + counts_text(families))
    print("  register values: " + counts_text(named))
    print("  replies with: " + counts_text(features))
    print("  wire values: " + counts_text(kinds))
    if refused:
        print("  the library refuses: " + counts_text(refused, by_count=True))
    gaps = [f for f, _regs, _w in REG_FAMILIES if not families[f]]
    gaps += [r for r in ("int8", "int16", "int32", "f32") if not features[r]]
    print("  coverage gaps: %s" % (", ".join(gaps) if gaps else "none"))


# --------------------------------------------------------------------------

def call_kinds(obj, meta, expected):
    """The summary rows a call counts in."""
    return ["all calls", obj["command"]]


def reply_kinds(obj, feats, expected):
    """The summary rows a reply counts in."""
    kinds = ["all replies"] + sorted(feats)
    data = bytes.fromhex(obj["data"])
    regs = [s.register for s in mp.parse_frame(data) if isinstance(s, mp.RegisterSubframe)]
    kinds += sorted({"registers: " + register_family(r) for r in regs})
    if len(set(regs)) != len(regs):
        kinds.append("repeated register")
    if isinstance(expected, Refused):
        kinds.append("library refuses")
    return kinds


def call_case(rng):
    """One call: (its JSON line, the line parsed, its arguments' resolutions
    and classes, the library's answer)."""
    while True:
        line, meta = gen_call(rng)
        # What motorwire reads is exactly what the library is given.
        text = json.dumps(line, allow_nan=False)
        obj = json.loads(text)
        expected = library_encode(obj)
        # Most calls too long for one frame are drawn again (a dense position
        # command with a query often is); a quarter are kept.
        if not (isinstance(expected, Refused) and expected.over_64) or rng.random() < 0.25:
            return text, obj, meta, expected


def dump(path, cases):
    """Writes the cases as {"input", "expected"} JSON lines."""
    with open(path, "w") as f:
        for text, obj, meta, expected in cases:
            exp = expected.to_json() if isinstance(expected, Refused) else expected
            f.write(json.dumps({"input": obj, "expected": exp}, allow_nan=False) + "\n")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--motorwire", help="the motorwire binary")
    parser.add_argument("--seed", type=int, required=True)
    parser.add_argument("--calls", type=int, default=10000)
    parser.add_argument("--replies", type=int, default=10000)
    parser.add_argument("--show", type=int, default=10,
                        help="mismatches to print, for encode and for decode each (default 10)")
    parser.add_argument("--dump-calls", metavar="FILE")
    parser.add_argument("--dump-replies", metavar="FILE")
    args = parser.parse_args()
    problems = signature_problems()
    if problems:
        print("moteus %s: the library's calls are not all covered by this script:" % moteus.VERSION)
        for p in problems:
            print("  " + p)
        print("FAILED: the generator must draw every keyword the library takes")
        return 1
    dumping = args.dump_calls or args.dump_replies
    if not dumping and not args.motorwire:
        parser.error("--motorwire is required (or --dump-calls / --dump-replies)")

    rng = random.Random(args.seed)
    calls = [call_case(rng) for _ in range(args.calls)]
    replies = []
    for _ in range(args.replies):
        line, feats = gen_reply(rng)
        text = json.dumps(line, allow_nan=False)
        obj = json.loads(text)
        replies.append((text, obj, feats, library_decode(obj)))

    print("moteus %s, seed %d" % (moteus.VERSION, args.seed))
    call_coverage(calls)
    reply_coverage(replies)
    if dumping:
        if args.dump_calls:
            dump(args.dump_calls, calls)
        if args.dump_replies:
            dump(args.dump_replies, replies)
        return 0

    ok = True
    outputs = run_motorwire(args.motorwire, "encode", [c[0] for c in calls])
    if outputs is None:
        return 1
    ok &= compare("encode", calls, outputs, explain_call, call_kinds, args.show,
                  "by argument", "by class of the value")
    outputs = run_motorwire(args.motorwire, "decode", [r[0] for r in replies])
    if outputs is None:
        return 1
    ok &= compare("decode", replies, outputs, explain_reply, reply_kinds, args.show,
                  "by register", "by kind of the wire value")
    print()
    print("all agree" if ok else "MISMATCH")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
