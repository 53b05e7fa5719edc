#!/usr/bin/env python3
"""Talk to a running `motorwire bridge` from Python, with the standard library only.

The bridge reads WIA JSON lines and answers each with exactly one result
line (`{"ok": ..., "line": N, ...}`); a move that went ahead is followed by
a completion line (`{"arrived": ..., "line": N, ...}`); feedback
(`{"feedback": ...}`) and events (`{"event": ...}`) come in between. Over a
local socket (`--input unix:PATH`) only processes of the same user can
connect; over TCP (`--input tcp:127.0.0.1:PORT --token-file FILE`) the first
line of a connection must be the token in FILE.

Start a bridge on its simulated arm, then run this against it:

    motorwire bridge --map fixtures/maps/demo-arm.toml --bus sim --input unix: &
    python3 examples/python/bridge_client.py --unix

    motorwire bridge --map fixtures/maps/demo-arm.toml --bus sim --input tcp:127.0.0.1:7878 --token-file ~/.config/motorwire/token &
    python3 examples/python/bridge_client.py --tcp 127.0.0.1:7878 --token-file ~/.config/motorwire/token

It moves the elbow, asks for a move outside the elbow's limits (refused,
nothing moves), and moves back; it checks each answer and exits 1 if one
is not what the bridge promises (so CI runs it), 0 otherwise.
"""

import argparse
import json
import os
import socket
import sys
import tempfile
import time


class Bridge:
    """One connection to a bridge: JSON lines out, JSON lines in."""

    def __init__(self, sock):
        self.sock = sock
        self.reader = sock.makefile("r", encoding="utf-8", newline="\n")
        self.sent = 0  # the bridge numbers a connection's lines from 1

    @classmethod
    def unix(cls, path, timeout=10.0):
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        sock.settimeout(timeout)
        sock.connect(path)
        return cls(sock)

    @classmethod
    def tcp(cls, address, token, timeout=10.0):
        host, _, port = address.rpartition(":")
        sock = socket.create_connection((host.strip("[]"), int(port)), timeout=timeout)
        bridge = cls(sock)
        # The first line is the token, not a command: it takes no line number.
        sock.sendall(token.encode("utf-8") + b"\n")
        return bridge

    def send(self, message):
        """Sends one JSON line; returns its line number."""
        self.sock.sendall(json.dumps(message).encode("utf-8") + b"\n")
        self.sent += 1
        return self.sent

    def read(self):
        line = self.reader.readline()
        if not line:
            raise ConnectionError("the bridge closed the connection")
        return json.loads(line)

    def wait_for(self, line, key, timeout=10.0):
        """The first line answering input line `line` that has `key`
        ("ok" for its result, "arrived" for its completion); feedback and
        events are skipped (an error from the bridge is raised)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = self.read()
            if message.get("line") == line and key in message:
                return message
            if "ok" in message and "line" not in message:
                raise RuntimeError("the bridge refused the connection: %s" % json.dumps(message))
        raise TimeoutError("no %r for line %d within %.0f s" % (key, line, timeout))

    def wait_event(self, name, timeout=10.0):
        """The first event `name`. `ready` comes to every client: with
        everyone's when the bridge becomes ready, or as a client's first
        line when it connects later, carrying every motor's state."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            message = self.read()
            if message.get("event") == name:
                return message
            if "ok" in message and "line" not in message:
                raise RuntimeError("the bridge refused the connection: %s" % json.dumps(message))
        raise TimeoutError("no %r event within %.0f s" % (name, timeout))

    def close(self):
        self.reader.close()
        self.sock.close()


def command(motor, setpoint):
    return {
        "motor_id": motor,
        "timestamp": int(time.time() * 1000),
        "control_mode": "position",
        "setpoint": setpoint,
    }


def check(condition, what, message):
    if not condition:
        print("FAIL: %s: %s" % (what, json.dumps(message)), file=sys.stderr)
        sys.exit(1)
    print("ok: %s" % what)


def session(bridge):
    # Ready: every motor's state, before the first command.
    ready = bridge.wait_event("ready")
    elbow = next(m for m in ready["motors"] if m["motor_id"] == "elbow")
    check(ready["latched"] is False and elbow["online"] is True and "position" in elbow,
          "ready: the elbow online at %s" % elbow.get("position"), ready)

    # A move within the limits: acked by the joint, then arrives.
    line = bridge.send(command("elbow", 40))
    result = bridge.wait_for(line, "ok")
    check(result["ok"] is True and result["acked"] == ["elbow"], "elbow to 40 acked", result)
    arrival = bridge.wait_for(line, "arrived")
    check(arrival["arrived"] is True and arrival["motors"][0]["target"] == 40.0,
          "elbow arrived at 40", arrival)

    # Outside the bus map's max_position 150: refused before any frame.
    line = bridge.send(command("elbow", 170))
    result = bridge.wait_for(line, "ok")
    # A refusal names its rule and the values it broke, for a program to
    # match on; the message is for a person.
    error = result.get("error", {})
    check(result["ok"] is False and error.get("kind") == "refused"
          and error.get("rule") == "outside_limit"
          and (error.get("field"), error.get("value"), error.get("limit"), error.get("limit_name"), error.get("limit_source"))
          == ("setpoint", 170.0, 150.0, "max_position", "bus map")
          and error.get("message") == "elbow: setpoint 170 is outside max_position (bus map) 150",
          "elbow to 170 refused: outside_limit, max_position 150 from the bus map", result)

    # And back.
    line = bridge.send(command("elbow", 0))
    result = bridge.wait_for(line, "ok")
    check(result["ok"] is True, "elbow to 0 acked", result)
    arrival = bridge.wait_for(line, "arrived")
    check(arrival["arrived"] is True, "elbow arrived at 0", arrival)


def default_socket():
    """Where `motorwire bridge --input unix:` listens: in $XDG_RUNTIME_DIR,
    or without it in a directory of this user's own under the temporary
    directory."""
    runtime = os.environ.get("XDG_RUNTIME_DIR")
    if runtime:
        return os.path.join(runtime, "motorwire.sock")
    return os.path.join(tempfile.gettempdir(), f"motorwire-{os.getuid()}", "motorwire.sock")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    where = parser.add_mutually_exclusive_group(required=True)
    where.add_argument(
        "--unix", metavar="PATH", nargs="?", const=default_socket(),
        help="the bridge's --input unix:PATH socket (alone: the bridge's own default for --input unix:)",
    )
    where.add_argument("--tcp", metavar="HOST:PORT", help="the bridge's --input tcp:HOST:PORT")
    parser.add_argument("--token-file", help="with --tcp: the bridge's --token-file")
    args = parser.parse_args()

    if args.unix:
        bridge = Bridge.unix(args.unix)
    else:
        if not args.token_file:
            parser.error("--tcp needs --token-file")
        with open(args.token_file, encoding="utf-8") as f:
            token = f.readline().rstrip("\n")
        bridge = Bridge.tcp(args.tcp, token)
    try:
        session(bridge)
    except (OSError, ValueError, KeyError, IndexError, RuntimeError) as e:
        print("FAIL: %s: %s" % (type(e).__name__, e), file=sys.stderr)
        sys.exit(1)
    finally:
        bridge.close()


if __name__ == "__main__":
    main()
