#!/usr/bin/env python3
"""Differential test of `motorwire servo encode|decode` against the vendors'
Python SDKs: Feetech's `scservo_sdk` (feetech-servo-sdk 1.0.0) and ROBOTIS's
`dynamixel_sdk` (dynamixel-sdk 4.1.0).

What it proves, on seeded random cases, for each protocol (`scs0`: Feetech
little-endian, `scs1`: Feetech big-endian, `dxl2`: Dynamixel Protocol 2.0):

- encode: for each instruction line (`{"instruction":"write","id":1,
  "address":42,"data":"0008"}`, every instruction the protocol has, data as
  hex or as a `value` of 1, 2 or 4 bytes), motorwire prints
  `{"bytes":"hex"}` equal to the bytes the SDK writes to its port for the
  same call (`ping`, `readTx`, `writeTxOnly`, `write{1,2,4}ByteTxOnly`,
  `regWriteTxOnly`, `action`, `reboot`, `factoryReset`, and the group
  classes `GroupSyncRead`, `GroupSyncWrite`, `GroupBulkRead`,
  `GroupBulkWrite`), captured by a port object that records what is
  written and answers nothing. Where the SDK writes nothing (a packet over
  its maximum, a ping or read of the broadcast id), motorwire must refuse
  the line too.
- decode: for each stream of bytes (a status packet built as a servo
  sends it, valid or corrupted: bytes flipped, cut short, noise before it,
  another packet after it, an impossible id or length, a wrong check),
  with or without the `length` a read asked for, motorwire prints the
  `{"id","error","params"}` the SDK's `rxPacket` reads from a port that
  gives those bytes (and `readRx`'s slice of `length` parameter bytes), or
  refuses where the SDK returns `COMM_RX_TIMEOUT` (`timeout`) or
  `COMM_RX_CORRUPT` (`incomplete` or `check`).

Two classes are the SDK's own faults, where motorwire does what the
protocol says, and are compared and counted apart:
- `dynamixel_sdk`'s `txPacket` computes the stuffed packet and sends the
  unstuffed one (it drops `addStuffing`'s result): for a packet whose
  instruction or parameters hold `FF FF FD`, motorwire's bytes must equal
  the SDK's own `addStuffing` of the packet, with the SDK's `updateCRC`.
- `readRx` takes `length` bytes after the error byte whatever the packet
  carries: for a packet with fewer parameters than asked, the SDK hands
  over its checksum and what follows as data; motorwire refuses it
  (`short`).

Status packets are otherwise read exactly as the SDK reads them, its
in-place `removeStuffing` included (after it has taken one stuffing byte
out it looks back at bytes it has already moved; motorwire does the same).

Run (the binary built beforehand; Python with both SDKs installed):

    python3 servo_reference.py --motorwire path/to/motorwire --seed 61 \\
        --instructions 5000 --statuses 3000 [--show 10]

It exits 1 on any mismatch or when motorwire prints a different number of
lines than it was given; 0 otherwise.
"""

import argparse
import json
import random
import subprocess
import sys
from collections import Counter

import dynamixel_sdk as dxl
import scservo_sdk as scs
import scservo_sdk.scservo_def as scs_def


class Port:
    """A port that records what is written and gives `stream` to reads."""

    def __init__(self, stream=b""):
        self.written = []
        self.stream = bytearray(stream)
        self.is_using = False

    def clearPort(self):
        pass

    def writePort(self, packet):
        self.written.append(bytes(packet))
        return len(packet)

    def readPort(self, length):
        n = max(0, min(length, len(self.stream)))
        out = list(self.stream[:n])
        del self.stream[:n]
        return out

    def setPacketTimeout(self, _):
        pass

    def setPacketTimeoutMillis(self, _):
        pass

    def isPacketTimeout(self):
        return len(self.stream) == 0

    def getBaudRate(self):
        return 1_000_000


# ---- instructions ---------------------------------------------------------

def draw_data(rng, protocol, big):
    """Data bytes: short mostly, a header inside sometimes, too long rarely."""
    if big:
        n = rng.randint(240, 260) if protocol != "dxl2" else rng.randint(1005, 1030)
    else:
        n = rng.choice([1, 2, 4, rng.randint(0, 24)])
    data = [rng.randrange(256) for _ in range(n)]
    if protocol == "dxl2" and n >= 3 and rng.random() < 0.25:
        at = rng.randrange(n - 2)
        data[at:at + 3] = [0xFF, 0xFF, 0xFD]
    return data


def draw_instruction(rng, protocol):
    dx = protocol == "dxl2"
    kinds = ["ping", "read", "write", "reg_write", "action", "sync_read", "sync_write"]
    if dx:
        kinds += ["reboot", "factory_reset", "bulk_read", "bulk_write"]
    kind = rng.choice(kinds)
    one = lambda: rng.randint(0, 252)  # noqa: E731
    any_id = lambda: 0xFE if rng.random() < 0.1 else one()  # noqa: E731
    addr_max = 0xFFFF if dx else 0xFF
    address = lambda: rng.randint(0, addr_max) if rng.random() < 0.3 else rng.randint(0, 150)  # noqa: E731
    big = rng.random() < 0.03
    line = {"instruction": kind}
    if kind == "ping":
        line["id"] = one()
    elif kind == "read":
        line.update(id=one(), address=address(), length=rng.randint(0, 255 if not dx else 300))
    elif kind in ("write", "reg_write"):
        line.update(id=any_id(), address=address())
        if kind == "write" and rng.random() < 0.4:
            n = rng.choice([1, 2, 4])
            bits = 8 * n
            # One byte is written as it is given (the SDK takes 0 to 255;
            # a negative one fails in its port); two and four bytes through
            # its byte macros, which take a negative value's two's
            # complement.
            low = 0 if n == 1 else -(1 << (bits - 1))
            v = rng.randint(low, (1 << bits) - 1)
            line.update(value=v, length=n)
        else:
            line["data"] = bytes(draw_data(rng, protocol, big)).hex()
    elif kind in ("action", "reboot"):
        line["id"] = any_id()
    elif kind == "factory_reset":
        line.update(id=any_id(), option=rng.choice([0x01, 0x02, 0xFF, rng.randrange(256)]))
    elif kind == "sync_read":
        ids = rng.sample(range(0, 253), rng.randint(1, 12))
        line.update(address=address(), length=rng.randint(1, 8), ids=ids)
    elif kind == "sync_write":
        n = rng.choice([1, 2, 4])
        count = rng.randint(1, 30 if big else 8)
        ids = rng.sample(range(0, 253), count)
        data = {}
        for i in ids:
            d = [rng.randrange(256) for _ in range(n)]
            if dx and n >= 3 and rng.random() < 0.1:
                d[0:3] = [0xFF, 0xFF, 0xFD]
            data[str(i)] = bytes(d).hex()
        line.update(address=address(), length=n, data=data)
    elif kind == "bulk_read":
        ids = rng.sample(range(0, 253), rng.randint(1, 10))
        line["reads"] = [[i, address(), rng.randint(1, 8)] for i in ids]
    elif kind == "bulk_write":
        ids = rng.sample(range(0, 253), rng.randint(1, 8))
        line["writes"] = [[i, address(), bytes(draw_data(rng, protocol, big and k == 0)).hex()]
                          for k, i in enumerate(ids)]
    return line


def sdk_handler(protocol):
    if protocol == "dxl2":
        return dxl.PacketHandler(2.0)
    ph = scs.PacketHandler(0 if protocol == "scs0" else 1)
    return ph


def value_bytes(protocol, value, n):
    """The SDK's own byte order for a value (its LOBYTE/HIBYTE macros)."""
    if protocol == "dxl2":
        lo, hi, lw, hw = dxl.DXL_LOBYTE, dxl.DXL_HIBYTE, dxl.DXL_LOWORD, dxl.DXL_HIWORD
    else:
        lo, hi, lw, hw = scs_def.SCS_LOBYTE, scs_def.SCS_HIBYTE, scs_def.SCS_LOWORD, scs_def.SCS_HIWORD
    if n == 1:
        return [value & 0xFF]
    if n == 2:
        return [lo(value), hi(value)]
    return [lo(lw(value)), hi(lw(value)), lo(hw(value)), hi(hw(value))]


def sdk_encode(protocol, line):
    """What the SDK writes for `line` (None where it writes nothing)."""
    ph = sdk_handler(protocol)
    port = Port()
    dx = protocol == "dxl2"
    mod = dxl if dx else scs
    k = line["instruction"]
    if k == "ping":
        ph.ping(port, line["id"])
    elif k == "read":
        ph.readTx(port, line["id"], line["address"], line["length"])
    elif k == "write" and "value" in line:
        fn = {1: ph.write1ByteTxOnly, 2: ph.write2ByteTxOnly, 4: ph.write4ByteTxOnly}[line["length"]]
        fn(port, line["id"], line["address"], line["value"])
    elif k in ("write", "reg_write"):
        data = list(bytes.fromhex(line["data"]))
        fn = ph.writeTxOnly if k == "write" else ph.regWriteTxOnly
        fn(port, line["id"], line["address"], len(data), data)
    elif k == "action":
        ph.action(port, line["id"])
    elif k == "reboot":
        ph.reboot(port, line["id"])
    elif k == "factory_reset":
        ph.factoryReset(port, line["id"], line["option"])
    elif k == "sync_read":
        g = mod.GroupSyncRead(port, ph, line["address"], line["length"])
        for i in line["ids"]:
            g.addParam(i)
        g.txPacket()
    elif k == "sync_write":
        g = mod.GroupSyncWrite(port, ph, line["address"], line["length"])
        for i, h in line["data"].items():
            g.addParam(int(i), list(bytes.fromhex(h)))
        g.txPacket()
    elif k == "bulk_read":
        g = dxl.GroupBulkRead(port, ph)
        for i, a, n in line["reads"]:
            g.addParam(i, a, n)
        g.txPacket()
    elif k == "bulk_write":
        g = dxl.GroupBulkWrite(port, ph)
        for i, a, h in line["writes"]:
            d = list(bytes.fromhex(h))
            g.addParam(i, a, len(d), d)
        g.txPacket()
    if not port.written:
        return None, False
    out = port.written[0]
    if dx:
        # The SDK's own stuffing of what it sent, with its own CRC: what
        # it meant to send (its txPacket drops addStuffing's result).
        body = list(out[:-2]) + [0, 0]
        stuffed = ph.addStuffing(list(body))
        if len(stuffed) != len(body):
            if len(stuffed) > dxl.protocol2_packet_handler.TXPACKET_MAX_LEN:
                return None, True
            crc = ph.updateCRC(0, stuffed, len(stuffed) - 2)
            stuffed[-2], stuffed[-1] = crc & 0xFF, crc >> 8
            return bytes(stuffed), True
    return out, False


def sdk_encode_or_raise(protocol, line):
    """`sdk_encode`, where the SDK raising (an over-long packet runs past
    `addStuffing`'s 1,024-byte buffer) is its refusal: it writes nothing."""
    try:
        return sdk_encode(protocol, line)
    except IndexError:
        return None, False


# ---- status packets -------------------------------------------------------

def feetech_status(sid, error, params):
    body = [sid, len(params) + 2, error] + params
    return bytes([0xFF, 0xFF] + body + [(~sum(body)) & 0xFF])


def dxl_status(ph, sid, error, params):
    raw = [0xFF, 0xFF, 0xFD, 0x00, sid, 0, 0, 0x55, error] + params
    n = len(params) + 4
    raw[5], raw[6] = n & 0xFF, n >> 8
    stuffed = ph.addStuffing(raw + [0, 0])
    crc = ph.updateCRC(0, stuffed, len(stuffed) - 2)
    stuffed[-2], stuffed[-1] = crc & 0xFF, crc >> 8
    return bytes(stuffed)


def draw_stream(rng, protocol, ph):
    dx = protocol == "dxl2"
    n = rng.choice([0, 1, 2, 4, rng.randint(0, 30)])
    params = [rng.randrange(256) for _ in range(n)]
    if dx and n >= 3 and rng.random() < 0.2:
        at = rng.randrange(n - 2)
        params[at:at + 3] = [0xFF, 0xFF, 0xFD]
    sid = rng.randint(0, 252)
    error = rng.randrange(0x80) if rng.random() < 0.3 else 0
    packet = dxl_status(ph, sid, error, params) if dx else feetech_status(sid, error, params)
    stream = bytearray(packet)
    cause = "valid"
    r = rng.random()
    if r < 0.15:
        cause = "flipped"
        for _ in range(rng.randint(1, 3)):
            stream[rng.randrange(len(stream))] ^= 1 << rng.randrange(8)
    elif r < 0.25:
        cause = "cut"
        stream = stream[:rng.randrange(len(stream))]
    elif r < 0.40:
        cause = "noise before"
        noise = bytes(rng.choice([0xFF, 0xFD, 0x00, rng.randrange(256)]) for _ in range(rng.randint(1, 12)))
        stream = bytearray(noise) + stream
    elif r < 0.50:
        cause = "packet after"
        stream += dxl_status(ph, rng.randint(0, 252), 0, [1, 2]) if dx else feetech_status(rng.randint(0, 252), 0, [1, 2])
    elif r < 0.58:
        cause = "impossible header"
        if dx:
            stream[rng.choice([3, 4, 6, 7])] = rng.choice([0xFD, 0xFF, 0x10])
        else:
            stream[rng.choice([2, 3, 4])] = rng.choice([0xFE, 0xFF, 0xFB, 0x80])
    elif r < 0.63:
        cause = "random bytes"
        stream = bytearray(rng.randrange(256) for _ in range(rng.randint(0, 40)))
    elif r < 0.66:
        cause = "empty"
        stream = bytearray()
    asked = None
    if rng.random() < 0.4:
        asked = rng.choice([n, max(0, n - 1), n + 1, rng.randint(0, 8)])
    return bytes(stream), asked, cause


def sdk_decode(protocol, ph, stream, asked):
    """What the SDK reads from a port giving `stream`: ("ok", dict),
    ("refused", kind), with the class of a known SDK fault where it is one."""
    port = Port(stream)
    dx = protocol == "dxl2"
    if dx:
        rx, result = ph.rxPacket(port, False)
        ok, timeout = dxl.COMM_SUCCESS, dxl.COMM_RX_TIMEOUT
    else:
        rx, result = ph.rxPacket(port)
        ok, timeout = scs.COMM_SUCCESS, scs.COMM_RX_TIMEOUT
    if result == timeout:
        return ("refused", "timeout"), None
    if result != ok:
        return ("refused", "corrupt"), None
    if dx:
        sid, error = rx[4], rx[8]
        carried = (rx[5] | rx[6] << 8) - 4
        first = 9
    else:
        sid, error = rx[2], rx[4]
        carried = rx[3] - 2
        first = 5
    carried = max(carried, 0)
    params = rx[first:first + carried]
    fault = None
    if asked is not None:
        if asked > carried:
            return ("refused", "short"), "the SDK reads past the packet (readRx)"
        params = params[:asked]
    return ("ok", {"id": sid, "error": error, "params": bytes(params).hex()}), fault


# ---- running motorwire ----------------------------------------------------

def run(motorwire, mode, protocol, lines):
    text = "".join(json.dumps(l) + "\n" for l in lines)
    p = subprocess.run([motorwire, "servo", mode, "--protocol", protocol], input=text,
                       capture_output=True, text=True, check=False)
    out = [json.loads(l) for l in p.stdout.splitlines()]
    if len(out) != len(lines):
        print(f"motorwire servo {mode} --protocol {protocol}: {len(out)} lines for {len(lines)}\n{p.stderr}")
        sys.exit(1)
    return out


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--motorwire", required=True)
    ap.add_argument("--seed", type=int, default=61)
    ap.add_argument("--instructions", type=int, default=5000)
    ap.add_argument("--statuses", type=int, default=3000)
    ap.add_argument("--show", type=int, default=10)
    a = ap.parse_args()
    rng = random.Random(a.seed)
    mismatches = Counter()
    shown = 0
    summary = []
    for protocol in ("scs0", "scs1", "dxl2"):
        ph = sdk_handler(protocol)
        # Encode.
        lines = [draw_instruction(rng, protocol) for _ in range(a.instructions)]
        expected = [sdk_encode_or_raise(protocol, l) for l in lines]
        got = run(a.motorwire, "encode", protocol, lines)
        counts = Counter()
        for line, (want, stuffed), g in zip(lines, expected, got):
            mine = bytes.fromhex(g["bytes"]) if "bytes" in g else None
            cls = "stuffed (the SDK's addStuffing)" if stuffed else ("both refused" if want is None else "equal")
            if mine == want:
                counts[cls] += 1
                continue
            mismatches[(protocol, "encode", line["instruction"], cls)] += 1
            if shown < a.show:
                shown += 1
                print(f"MISMATCH {protocol} encode {json.dumps(line)}\n  sdk:       {want.hex() if want else None}\n  motorwire: {g}")
        summary.append(f"{protocol} encode: {a.instructions} instructions: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
        # Decode.
        cases = [draw_stream(rng, protocol, ph) for _ in range(a.statuses)]
        lines = []
        for stream, asked, _ in cases:
            l = {"bytes": stream.hex()}
            if asked is not None:
                l["length"] = asked
            lines.append(l)
        got = run(a.motorwire, "decode", protocol, lines)
        counts = Counter()
        for (stream, asked, cause), line, g in zip(cases, lines, got):
            (verdict, want), fault = sdk_decode(protocol, ph, stream, asked)
            if verdict == "ok":
                same = g == want
            else:
                kind = g.get("error", "") if isinstance(g.get("error"), str) else ""
                kind = kind.split(":")[0]
                same = kind == want or (want == "corrupt" and kind in ("incomplete", "check"))
            cls = fault or (f"{cause}, read" if verdict == "ok" else f"{cause}, refused")
            if same:
                counts[cls] += 1
                continue
            mismatches[(protocol, "decode", cause, verdict)] += 1
            if shown < a.show:
                shown += 1
                print(f"MISMATCH {protocol} decode {json.dumps(line)} ({cause})\n  sdk:       {verdict} {want}\n  motorwire: {g}")
        summary.append(f"{protocol} decode: {a.statuses} streams: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    for s in summary:
        print(s)
    if mismatches:
        print("mismatches by cause:")
        for k, v in sorted(mismatches.items()):
            print(f"  {v:6} {k}")
        sys.exit(1)
    print("no mismatch")


if __name__ == "__main__":
    main()
