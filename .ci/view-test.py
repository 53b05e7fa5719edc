#!/usr/bin/env python3
"""The live view (`motorwire bridge --view`) in a real browser.

Starts a bridge on the simulated bus with its view on a loopback port and
its input on a unix socket, opens the page in headless Chromium (driven
over the DevTools protocol: a WebSocket, spoken here with the standard
library alone), moves the elbow and triggers an emergency stop through the
socket, and asserts from the page's DOM that:
- the elbow's plotted position follows the feedback the bridge sent (its
  last plotted value is one of the positions the socket client received,
  and it reaches the target);
- the plot is redrawn at least 20 times a second;
- the stop appears as a mark on the elbow's charts and in the event list,
  and the page shows the stop latched.
A screenshot is kept at target/view.png for a person to look at.

Usage: view-test.py MOTORWIRE [CHROMIUM]   (from the repository root)
"""

import base64
import json
import os
import re
import socket
import subprocess
import sys
import tempfile
import time
import urllib.request

MOTORWIRE = sys.argv[1]
CHROMIUM = sys.argv[2] if len(sys.argv) > 2 else "chromium"


def fail(why):
    print(f"view-test: FAILED: {why}", file=sys.stderr)
    sys.exit(1)


class WebSocket:
    """Just enough of RFC 6455 for the DevTools protocol: text frames."""

    def __init__(self, url):
        m = re.match(r"ws://([^:/]+):(\d+)(/.*)", url)
        if not m:
            fail(f"not a ws:// address: {url}")
        host, port, path = m.group(1), int(m.group(2)), m.group(3)
        self.sock = socket.create_connection((host, port), timeout=30)
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall(
            (
                f"GET {path} HTTP/1.1\r\nHost: {host}:{port}\r\nUpgrade: websocket\r\n"
                f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n"
            ).encode()
        )
        head = b""
        while b"\r\n\r\n" not in head:
            chunk = self.sock.recv(1)
            if not chunk:
                fail("the DevTools socket closed during its handshake")
            head += chunk
        if b" 101 " not in head.split(b"\r\n", 1)[0]:
            fail(f"DevTools handshake: {head!r}")

    def _exactly(self, n):
        data = b""
        while len(data) < n:
            chunk = self.sock.recv(n - len(data))
            if not chunk:
                fail("the DevTools socket closed")
            data += chunk
        return data

    def send(self, text):
        payload = text.encode()
        head = bytes([0x81])
        n = len(payload)
        if n < 126:
            head += bytes([0x80 | n])
        elif n < 65536:
            head += bytes([0x80 | 126]) + n.to_bytes(2, "big")
        else:
            head += bytes([0x80 | 127]) + n.to_bytes(8, "big")
        mask = os.urandom(4)
        self.sock.sendall(head + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def recv(self):
        message = b""
        while True:
            b0, b1 = self._exactly(2)
            n = b1 & 0x7F
            if n == 126:
                n = int.from_bytes(self._exactly(2), "big")
            elif n == 127:
                n = int.from_bytes(self._exactly(8), "big")
            payload = self._exactly(n)
            opcode = b0 & 0x0F
            if opcode == 8:
                fail("the DevTools socket was closed by the browser")
            if opcode in (0, 1, 2):
                message += payload
                if b0 & 0x80:
                    return message.decode()


class Page:
    def __init__(self, ws):
        self.ws = ws
        self.next_id = 0

    def call(self, method, **params):
        self.next_id += 1
        self.ws.send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            msg = json.loads(self.ws.recv())
            if msg.get("id") == self.next_id:
                if "error" in msg:
                    fail(f"{method}: {msg['error']}")
                return msg.get("result", {})

    def eval(self, expression):
        r = self.call("Runtime.evaluate", expression=expression, returnByValue=True)
        if "exceptionDetails" in r:
            fail(f"in the page: {expression}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def wait(self, expression, what, limit=15.0):
        end = time.time() + limit
        while time.time() < end:
            v = self.eval(expression)
            if v:
                return v
            time.sleep(0.1)
        fail(f"within {limit} s: {what}")


def read_until(stream, pattern, limit, what):
    end = time.time() + limit
    buf = ""
    while time.time() < end:
        line = stream.readline()
        if not line:
            break
        buf += line
        m = re.search(pattern, line)
        if m:
            return m
    fail(f"{what}; got:\n{buf}")


def main():
    os.makedirs("target", exist_ok=True)
    work = tempfile.mkdtemp(prefix="motorwire-view-")
    sock_path = os.path.join(work, "bridge.sock")
    bridge = subprocess.Popen(
        [MOTORWIRE, "bridge", "--map", "fixtures/maps/demo-arm.toml", "--bus", "sim",
         "--input", f"unix:{sock_path}", "--feedback-hz", "20", "--view", "127.0.0.1:0"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    browser = None
    try:
        url = read_until(bridge.stderr, r"the live view at (http://\S+/)", 20, "the bridge never said where its view is").group(1)
        browser = subprocess.Popen(
            [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu", "--no-first-run",
             "--remote-debugging-port=0", f"--user-data-dir={work}/chromium",
             # Another site's name made to resolve to this machine, as a
             # DNS-rebinding page does: the view must not answer it.
             "--host-resolver-rules=MAP rebind.attacker.test 127.0.0.1", "about:blank"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
        devtools = read_until(browser.stderr, r"DevTools listening on (ws://\S+)", 30, "Chromium never opened its DevTools port").group(1)
        port = re.match(r"ws://[^:]+:(\d+)/", devtools).group(1)
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list", timeout=10))
        page_ws = next(t["webSocketDebuggerUrl"] for t in targets if t["type"] == "page")
        page = Page(WebSocket(page_ws))
        page.call("Emulation.setDeviceMetricsOverride", width=1400, height=1100, deviceScaleFactor=1, mobile=False)
        page.call("Page.navigate", url=url)
        page.wait("document.querySelector('section[data-motor=elbow]') !== null && document.getElementById('status').dataset.state === 'live'",
                  "the page shows the elbow, its stream live")

        client = socket.socket(socket.AF_UNIX)
        client.settimeout(20)
        client.connect(sock_path)
        lines = client.makefile("r", encoding="utf-8")
        read_until(lines, r'"event":"ready"', 20, "no ready on the socket")
        page.wait("document.querySelector('section[data-motor=elbow]').dataset.online === 'true'",
                  "the elbow shown online")

        # Redrawn at least 20 times a second: count the plot's changes for
        # a second.
        page.eval("""window.__redraws = 0; new MutationObserver(() => window.__redraws++).observe(
            document.querySelector('section[data-motor=elbow] svg[data-quantity=position] polyline.measured'),
            {attributes: true, attributeFilter: ['points']}); 0""")
        t0 = time.time()
        time.sleep(1.0)
        redraws = page.eval("window.__redraws")
        per_s = redraws / (time.time() - t0)
        if per_s < 20:
            fail(f"the page was redrawn {redraws} times in a second (at least 20 expected)")

        now = int(time.time() * 1000)
        client.sendall((json.dumps({"motor_id": "elbow", "timestamp": now, "control_mode": "position", "setpoint": 30}) + "\n").encode())
        positions = []
        end = time.time() + 10
        while time.time() < end:
            v = json.loads(lines.readline())
            fb = v.get("feedback")
            if fb and fb.get("motor_id") == "elbow":
                positions.append(fb["position"])
            if v.get("arrived") is not None and v.get("line") == 1:
                break
        if not v.get("arrived"):
            fail(f"the elbow did not arrive: {v}")
        moving = [p for p in positions if 0.5 < p < 29.5]
        if len(moving) < 5:
            fail(f"too few feedback lines in motion: {positions}")
        # The page's last plotted position is what the feedback said last
        # (the same number), and at the target.
        last = page.wait("""(() => { const p = document.querySelector('section[data-motor=elbow] svg[data-quantity=position] polyline.measured');
            const v = Number(p.dataset.last); return Math.abs(v - 30) < 0.5 ? String(v) : null; })()""",
                         "the elbow plotted at 30")
        def more_feedback(seconds):
            end = time.time() + seconds
            while time.time() < end:
                fb = json.loads(lines.readline()).get("feedback")
                if fb and fb.get("motor_id") == "elbow":
                    positions.append(fb["position"])

        more_feedback(0.5)
        last = float(page.eval("document.querySelector('section[data-motor=elbow] svg[data-quantity=position] polyline.measured').dataset.last"))
        more_feedback(0.5)
        if not any(abs(last - p) < 1e-6 for p in positions[-40:]):
            fail(f"the plotted position {last} is not one the feedback gave: {positions[-20:]}")
        plotted = page.eval("Number(document.querySelector('section[data-motor=elbow] svg[data-quantity=position] polyline.measured').dataset.points)")
        if plotted < len(moving):
            fail(f"{plotted} points plotted, fewer than the {len(moving)} feedback lines in motion")
        target = page.eval("document.querySelector('section[data-motor=elbow] svg[data-quantity=position] polyline.target').getAttribute('points')")
        if not target:
            fail("no target drawn for the elbow")

        # A SafetyLimits line narrows the elbow to 0..100: the page shades
        # the limits now in force, not the bus map's (0..150).
        bands = "document.querySelectorAll('section[data-motor=elbow] svg[data-quantity=position] rect.band')"
        if page.eval(f"{bands}[0].dataset.limit") != "150":
            fail(f"the elbow's upper band did not start at the bus map's 150: {page.eval(f'{bands}[0].dataset.limit')}")
        client.sendall(b'{"motor_id":"elbow","position_limits":{"min":0,"max":100},"velocity_limits":{"max_velocity":120},"torque_limits":{"continuous_torque":5,"peak_torque":5}}\n')
        read_until(lines, r'"ok":true,"line":2', 10, "the SafetyLimits line was not taken")
        page.wait(f"{bands}[0].dataset.limit === '100' && {bands}[1].dataset.limit === '0'",
                  "the limits in force (0..100) shaded")
        client.sendall(b'{"emergency_stop":true}\n')
        page.wait("document.querySelector('section[data-motor=elbow] svg[data-quantity=position] g.mark[data-kind=stop]') !== null",
                  "the stop marked on the elbow's chart")
        label = page.wait("(() => { const e = document.querySelector('#events li[data-kind=stop]'); return e && e.textContent; })()",
                          "the stop in the event list")
        if "emergency stop (input)" not in label:
            fail(f"the stop's label: {label}")
        page.wait("document.getElementById('latched').dataset.latched === 'true'", "the stop shown latched")
        inputs = page.eval("document.getElementById('inputs').textContent")
        if '"emergency_stop":true' not in inputs or '"setpoint": 30' not in inputs:
            fail(f"the input lines not shown as they came: {inputs}")
        time.sleep(0.3)
        shot = page.call("Page.captureScreenshot", format="png")
        with open("target/view.png", "wb") as f:
            f.write(base64.b64decode(shot["data"]))
        # The same view under another site's name (DNS rebinding): refused,
        # its stream too.
        rebound = url.replace("127.0.0.1", "rebind.attacker.test")
        page.call("Page.navigate", url=rebound)
        shown = page.wait("document.readyState === 'complete' && location.hostname === 'rebind.attacker.test' && document.body && document.body.innerText",
                          "the rebound page loaded")
        if "Host is not this view's address" not in shown or "elbow" in shown:
            fail(f"the view answered another site's name: {shown[:200]}")
        status = page.call("Runtime.evaluate", expression="fetch('/events').then(r => r.status)",
                           awaitPromise=True, returnByValue=True)["result"].get("value")
        if status != 403:
            fail(f"the rebound page's /events answered {status}")
        print(f"view-test: the elbow plotted at {last} (the feedback's last), {plotted} points, "
              f"redrawn {per_s:.0f} times a second, the stop marked and latched; "
              f"under a rebound name the page and its stream refused (403); screenshot target/view.png")
        client.close()
    finally:
        if browser:
            browser.kill()
            browser.wait()
        bridge.send_signal(2)
        try:
            bridge.wait(timeout=30)
        except subprocess.TimeoutExpired:
            bridge.kill()


if __name__ == "__main__":
    main()
