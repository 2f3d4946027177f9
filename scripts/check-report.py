#!/usr/bin/env python3
"""Check a friction-identify HTML report in a real browser (headless Chromium).

    python3 scripts/check-report.py REPORT.html [--expect ID ...] [--expect-kind KIND=N ...]
                                    [--min-marks N] [--screenshot OUT.png] [--chromium PATH]

Chromium is driven over the DevTools protocol on a pipe (--remote-debugging-pipe: messages are
JSON texts separated by NUL bytes on file descriptors 3 and 4), so only the Python standard
library is needed.  The page is loaded from its file with a 1280-pixel-wide window, and the check
fails (exit status 1, one line per failure) when

  * the page raises a console error, an uncaught exception, or a log entry of level error (SVG
    attributes Chromium cannot parse, a refused or failed load: the report's Content-Security-
    Policy forbids every fetch), or asks for anything that is not the file itself or a data: URL;
  * an expected plot (an <svg class="plot"> with that id) is missing, or fewer plots of a kind
    (data-kind) than expected are there;
  * a panel of a plot has fewer than --min-marks marks (path vertices, bars) with finite
    coordinates inside the SVG's viewBox, read from the DOM as the browser holds it after load;
  * a plot has no axis label with a unit ("quantity [unit]") on each axis;
  * in the screenshot, a panel's plot area is only background: fewer than 0.1 % of its pixels
    (and fewer than 50) differ clearly from the area's most common colour.  The screenshot is
    taken by the browser of each plot area and decoded here (PNG: zlib and the five filters).

Exit status 0 when every check passes; 1 when one fails; 2 when the browser cannot be run.
"""

import argparse
import array
import base64
import collections
import html.parser
import json
import math
import os
import re
import shutil
import struct
import subprocess
import sys
import tempfile
import time
import zlib


# ---- the DevTools protocol over a pipe ---------------------------------------------------------


class Browser:
    def __init__(self, chromium, width):
        self.user_data = tempfile.mkdtemp(prefix="friction-report-check-")
        to_child_r, to_child_w = os.pipe()
        from_child_r, from_child_w = os.pipe()

        def plumb():  # in the child: the protocol pipe is fd 3 (in) and fd 4 (out)
            os.dup2(to_child_r, 3)
            os.dup2(from_child_w, 4)

        args = [
            chromium, "--headless", "--no-sandbox", "--disable-gpu", "--disable-quic",
            "--no-first-run", "--disable-background-networking", "--disable-component-update",
            "--disable-sync", "--disable-extensions", "--hide-scrollbars", "--mute-audio",
            "--disable-dev-shm-usage",
            "--user-data-dir=" + self.user_data, "--remote-debugging-pipe",
            "--window-size=%d,900" % width, "about:blank",
        ]
        self.proc = subprocess.Popen(args, pass_fds=(3, 4), preexec_fn=plumb,
                                     stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                                     stderr=subprocess.DEVNULL)
        os.close(to_child_r)
        os.close(from_child_w)
        self.out = to_child_w
        self.inp = from_child_r
        self.buffer = b""
        self.next_id = 0
        self.events = []
        self.session = None

    def _read(self, deadline):
        while b"\0" not in self.buffer:
            if time.monotonic() > deadline:
                raise TimeoutError("no answer from the browser")
            chunk = os.read(self.inp, 1 << 20)
            if not chunk:
                raise EOFError("the browser closed the protocol pipe")
            self.buffer += chunk
        message, _, self.buffer = self.buffer.partition(b"\0")
        return json.loads(message)

    def call(self, method, params=None, timeout=60, session=True):
        self.next_id += 1
        message = {"id": self.next_id, "method": method, "params": params or {}}
        if session and self.session:
            message["sessionId"] = self.session
        os.write(self.out, json.dumps(message).encode() + b"\0")
        deadline = time.monotonic() + timeout
        while True:
            m = self._read(deadline)
            if m.get("id") == self.next_id:
                if "error" in m:
                    raise RuntimeError("%s: %s" % (method, m["error"].get("message")))
                return m.get("result", {})
            self.events.append(m)

    def wait_for(self, event, timeout=60):
        deadline = time.monotonic() + timeout
        while not any(e.get("method") == event for e in self.events):
            self.events.append(self._read(deadline))

    def open(self, url):
        target = self.call("Target.createTarget", {"url": "about:blank"}, session=False)
        self.session = self.call("Target.attachToTarget",
                                 {"targetId": target["targetId"], "flatten": True},
                                 session=False)["sessionId"]
        for domain in ("Page.enable", "Runtime.enable", "Log.enable", "Network.enable"):
            self.call(domain)
        self.events.clear()
        start = time.monotonic()
        self.call("Page.navigate", {"url": url})
        self.wait_for("Page.loadEventFired")
        return time.monotonic() - start

    def evaluate(self, expression):
        r = self.call("Runtime.evaluate", {"expression": expression, "returnByValue": True})
        if "exceptionDetails" in r:
            raise RuntimeError("evaluate: %s" % r["exceptionDetails"].get("text"))
        return r["result"].get("value")

    def close(self):
        try:
            self.call("Browser.close", session=False, timeout=10)
        except Exception:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        os.close(self.out)
        os.close(self.inp)
        shutil.rmtree(self.user_data, ignore_errors=True)


# ---- PNG decoding (the standard library has zlib; the filters are written out) --------------


def decode_png(data):
    """Returns (width, height, channels, rows): rows as bytes objects of width*channels."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, header = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
    width, height, depth, colour, _, _, interlace = header
    if depth != 8 or interlace != 0 or colour not in (0, 2, 4, 6):
        raise ValueError("unsupported PNG (depth %d, colour type %d, interlace %d)"
                         % (depth, colour, interlace))
    channels = {0: 1, 2: 3, 4: 2, 6: 4}[colour]
    raw = zlib.decompress(b"".join(idat))
    stride = width * channels
    # Up, the filter of Chromium's screenshots taken with optimizeForSpeed, adds the row above
    # byte by byte: done on the whole row as one integer, the carries kept inside each byte.
    low = int.from_bytes(b"\x7f" * stride, "big")
    high = int.from_bytes(b"\x80" * stride, "big")
    rows, previous = [], bytearray(stride)
    for y in range(height):
        start = y * (stride + 1)
        kind = raw[start]
        line = bytearray(raw[start + 1:start + 1 + stride])
        if kind == 2:  # Up
            a, b = int.from_bytes(line, "big"), int.from_bytes(previous, "big")
            line = bytearray((((a & low) + (b & low)) ^ ((a ^ b) & high)).to_bytes(stride, "big"))
        elif kind == 1:  # Sub
            for i in range(channels, stride):
                line[i] = (line[i] + line[i - channels]) & 255
        elif kind == 3:  # Average
            for i in range(stride):
                left = line[i - channels] if i >= channels else 0
                line[i] = (line[i] + ((left + previous[i]) >> 1)) & 255
        elif kind == 4:  # Paeth
            for i in range(stride):
                a = line[i - channels] if i >= channels else 0
                b = previous[i]
                c = previous[i - channels] if i >= channels else 0
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                line[i] = (line[i] + (a if pa <= pb and pa <= pc else b if pb <= pc else c)) & 255
        elif kind != 0:
            raise ValueError("bad PNG filter %d" % kind)
        rows.append(bytes(line))
        previous = line
    return width, height, channels, rows


def ink(png, inset=3, threshold=80):
    """Pixels of a plot area that differ clearly from its most common colour (its background)."""
    width, height, channels, rows = decode_png(png)
    c = min(channels, 3)
    # The colours counted first (a plot area has a few thousand among its pixels), then each
    # colour judged once.
    pixels = collections.Counter()
    for row in rows[inset:height - inset]:
        inner = row[inset * channels:(width - inset) * channels]
        if channels == 4:  # RGBA: a pixel is one 32-bit word, counted at C speed
            pixels.update(array.array("I", inner))
        else:
            pixels.update(inner[i:i + channels] for i in range(0, len(inner), channels))
    colours = collections.Counter()
    for p, n in pixels.items():
        colours[p.to_bytes(4, sys.byteorder)[:c] if channels == 4 else p[:c]] += n
    if not colours:
        return 0, 0
    background = colours.most_common(1)[0][0]
    count = sum(n for p, n in colours.items()
                if p != background and max(abs(p[i] - background[i]) for i in range(c)) > threshold)
    return count, sum(colours.values())


# ---- the DOM -----------------------------------------------------------------------------------


def path_vertices(d):
    """Vertices of an SVG path's data (absolute and relative M L H V, Z); a token that is not a
    number where a coordinate belongs (NaN, inf) gives a non-finite vertex."""
    tokens = re.findall(r"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?|[A-Za-z]+", d)
    out, command, x, y, start = [], "M", 0.0, 0.0, (0.0, 0.0)

    def num(t):
        try:
            return float(t)
        except ValueError:
            return float("nan")

    i = 0
    while i < len(tokens):
        t = tokens[i]
        if re.fullmatch(r"[MLHVZmlhvz]", t):
            command = t
            i += 1
            if command in "Zz":
                x, y = start
                command = "L"
            continue
        if re.fullmatch(r"[A-Za-z]+", t) and t.lower() not in ("nan", "inf", "infinity"):
            # A command this checker does not interpret (curves): skip its numbers.
            command = "?"
            i += 1
            continue
        if command in "MLml":
            if i + 1 >= len(tokens):
                break
            a, b = num(tokens[i]), num(tokens[i + 1])
            i += 2
            if command in "ml":
                a, b = x + a, y + b
            x, y = a, b
            if command in "Mm":
                start = (x, y)
                command = "L" if command == "M" else "l"
            out.append((x, y))
        elif command in "HhVv":
            a = num(tokens[i])
            i += 1
            if command == "H":
                x = a
            elif command == "h":
                x = x + a
            elif command == "V":
                y = a
            else:
                y = y + a
            if command in "hv" and a == 0:
                continue  # a dot: "M x y h0" is one mark
            out.append((x, y))
        else:
            i += 1
    return out


class PlotParser(html.parser.HTMLParser):
    """Collects every <svg class="plot">: id, kind, viewBox, axis labels and per-panel marks."""

    def __init__(self):
        super().__init__()
        self.plots = []
        self.stack = []  # open elements: (tag, attrs)
        self.text_target = None

    def handle_starttag(self, tag, attrs):
        a = dict(attrs)
        classes = (a.get("class") or "").split()
        self.stack.append((tag, classes))
        if tag == "svg" and "plot" in classes:
            vb = [float(v) for v in (a.get("viewbox") or "0 0 0 0").split()]
            self.plots.append({"id": a.get("id"), "kind": a.get("data-kind"), "viewBox": vb,
                               "panels": [], "labels": {"x": [], "y": []}})
            return
        if not self.plots or not any(t == "svg" for t, _ in self.stack[:-1]):
            return
        plot = self.plots[-1]
        if tag == "g" and "panel" in classes:
            plot["panels"].append({"name": a.get("data-panel"), "marks": 0, "bad": 0})
            return
        in_marks = any(t == "g" and "marks" in c for t, c in self.stack[:-1])
        if tag == "text" and "axis-label" in classes:
            self.text_target = ("x" if "x" in classes else "y", [])
        if not in_marks or not plot["panels"]:
            return
        panel = plot["panels"][-1]
        points = []
        if tag == "path":
            points = path_vertices(a.get("d") or "")
        elif tag == "rect":
            try:
                x, y = float(a.get("x")), float(a.get("y"))
                w, h = float(a.get("width")), float(a.get("height"))
                points = [(x + w / 2, y + h / 2)]
            except (TypeError, ValueError):
                points = [(float("nan"), float("nan"))]
        elif tag in ("circle", "ellipse"):
            try:
                points = [(float(a.get("cx")), float(a.get("cy")))]
            except (TypeError, ValueError):
                points = [(float("nan"), float("nan"))]
        vx, vy, vw, vh = plot["viewBox"]
        for px, py in points:
            if (math.isfinite(px) and math.isfinite(py) and vx <= px <= vx + vw
                    and vy <= py <= vy + vh):
                panel["marks"] += 1
            else:
                panel["bad"] += 1

    def handle_endtag(self, tag):
        while self.stack:
            t, _ = self.stack.pop()
            if t == tag:
                break
        if tag == "text" and self.text_target:
            axis, parts = self.text_target
            self.plots[-1]["labels"][axis].append("".join(parts))
            self.text_target = None

    def handle_data(self, data):
        if self.text_target:
            self.text_target[1].append(data)


GEOMETRY = """
(() => {
  const out = [];
  for (const svg of document.querySelectorAll('svg.plot')) {
    const areas = svg.querySelectorAll('.plot-area');
    areas.forEach((r, k) => {
      const b = r.getBoundingClientRect();
      out.push({id: svg.id, panel: k, x: b.left + window.scrollX, y: b.top + window.scrollY,
                width: b.width, height: b.height});
    });
  }
  return {plots: out, width: document.documentElement.scrollWidth,
          height: document.documentElement.scrollHeight};
})()
"""


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("report")
    ap.add_argument("--expect", action="append", default=[], help="id of a plot that must exist")
    ap.add_argument("--expect-kind", action="append", default=[],
                    help="KIND=N: at least N plots of data-kind KIND")
    ap.add_argument("--min-marks", type=int, default=20,
                    help="marks a panel needs (bar charts: 2)")
    ap.add_argument("--screenshot", help="save the top of the page (1280 x 1400) as a PNG")
    ap.add_argument("--screenshot-height", type=int, default=1400)
    ap.add_argument("--screenshot-scale", type=float, default=1.0)
    ap.add_argument("--screenshot-from", help="id of the element the screenshot starts at")
    ap.add_argument("--timing", action="store_true",
                    help="also time the layout and paint of the whole page")
    ap.add_argument("--chromium", default=os.environ.get("CHROMIUM", "chromium"))
    ap.add_argument("--width", type=int, default=1280)
    args = ap.parse_args()

    path = os.path.abspath(args.report)
    if not os.path.isfile(path):
        print("check-report: %s: no such file" % args.report)
        return 1
    if shutil.which(args.chromium) is None:
        print("check-report: %s not found (scripts/setup.sh installs Debian's chromium)"
              % args.chromium)
        return 2
    url = "file://" + path
    failures = []
    started = time.monotonic()
    browser = Browser(args.chromium, args.width)
    try:
        loaded = browser.open(url)
        painted = None
        if args.timing:
            # Layout and paint of the whole page: a viewport as tall as the page, then two
            # animation frames (the second starts once the first has been painted).
            height = browser.evaluate("document.documentElement.scrollHeight")
            t0 = time.monotonic()
            browser.call("Emulation.setDeviceMetricsOverride",
                         {"width": args.width, "height": min(height, 16000),
                          "deviceScaleFactor": 1, "mobile": False})
            browser.call("Runtime.evaluate", {
                "expression": "new Promise(r => requestAnimationFrame(() => "
                              "requestAnimationFrame(() => r(1))))",
                "awaitPromise": True}, timeout=300)
            painted = time.monotonic() - t0
        browser.call("Emulation.setDeviceMetricsOverride",
                     {"width": args.width, "height": 900, "deviceScaleFactor": 1,
                      "mobile": False})
        dom = browser.evaluate("document.documentElement.outerHTML")
        geometry = browser.evaluate(GEOMETRY)
        shots = {}
        for g in geometry["plots"]:
            if g["width"] < 8 or g["height"] < 8:
                shots[(g["id"], g["panel"])] = None
                continue
            r = browser.call("Page.captureScreenshot", {
                "format": "png", "captureBeyondViewport": True,
                "clip": {"x": g["x"], "y": g["y"], "width": g["width"], "height": g["height"],
                         "scale": 1},
                # Faster to encode, and its rows come with the Up filter, fast to decode here.
                "optimizeForSpeed": True})
            shots[(g["id"], g["panel"])] = base64.b64decode(r["data"])
        if args.screenshot:
            top = 0
            if args.screenshot_from:
                top = browser.evaluate(
                    "(() => { const e = document.getElementById(%s); return e ? "
                    "e.getBoundingClientRect().top + window.scrollY : 0; })()"
                    % json.dumps(args.screenshot_from))
            r = browser.call("Page.captureScreenshot", {
                "format": "png", "captureBeyondViewport": True,
                "clip": {"x": 0, "y": top, "width": args.width,
                         "height": min(args.screenshot_height, geometry["height"] - top),
                         "scale": args.screenshot_scale}})
            with open(args.screenshot, "wb") as f:
                f.write(base64.b64decode(r["data"]))
        # Let late messages arrive (rendering errors are logged as the page paints).
        browser.evaluate("1")
        events = list(browser.events)
    finally:
        browser.close()

    # Console, exceptions, log entries, requests.
    for e in events:
        method, p = e.get("method"), e.get("params", {})
        if method == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
            text = " ".join(str(a.get("value", a.get("description", ""))) for a in p.get("args", []))
            failures.append("console %s: %s" % (p.get("type"), text))
        elif method == "Runtime.exceptionThrown":
            failures.append("uncaught exception: %s"
                            % p.get("exceptionDetails", {}).get("text", "?"))
        elif method == "Log.entryAdded" and p.get("entry", {}).get("level") == "error":
            entry = p["entry"]
            failures.append("console error (%s): %s" % (entry.get("source"), entry.get("text")))
        elif method == "Network.requestWillBeSent":
            u = p.get("request", {}).get("url", "")
            if u != url and not u.startswith("data:"):
                failures.append("the page asks for %s (a report must need nothing but itself)" % u)

    parser = PlotParser()
    parser.feed(dom)
    plots = {p["id"]: p for p in parser.plots}
    for want in args.expect:
        if want not in plots:
            failures.append("expected plot %s is missing" % want)
    kinds = collections.Counter(p["kind"] for p in parser.plots)
    for spec in args.expect_kind:
        kind, _, n = spec.partition("=")
        if kinds[kind] < int(n or 1):
            failures.append("expected at least %s plot(s) of kind %s, found %d"
                            % (n or 1, kind, kinds[kind]))
    if not parser.plots:
        failures.append("the page has no plot")

    unit = re.compile(r"\S.*\[[^\]]+\]")
    for p in parser.plots:
        pid = p["id"]
        for axis in ("x", "y"):
            if p["kind"] == "bars" and axis == "y":
                continue  # categories, not a quantity
            if not any(unit.search(t) for t in p["labels"][axis]):
                failures.append("%s: no %s-axis label with a unit" % (pid, axis))
        if not p["panels"]:
            failures.append("%s: no panel" % pid)
        need = 2 if p["kind"] == "bars" else args.min_marks
        for k, panel in enumerate(p["panels"]):
            if panel["marks"] < need:
                failures.append("%s, panel %s: %d marks with finite coordinates inside the "
                                "viewBox (%d outside or not finite); at least %d expected"
                                % (pid, panel["name"], panel["marks"], panel["bad"], need))
            png = shots.get((pid, k))
            if png is None:
                failures.append("%s, panel %s: the plot area is not rendered" % (pid, panel["name"]))
                continue
            n_ink, n = ink(png)
            panel["ink"] = (n_ink, n)
            if n_ink < max(50, 0.001 * n):
                failures.append("%s, panel %s: the screenshot of the plot area is only background "
                                "(%d of %d pixels differ from it)" % (pid, panel["name"], n_ink, n))

    for p in parser.plots:
        marks = ", ".join("%s %d marks %.1f %% ink" % (q["name"], q["marks"],
                                                        100.0 * q.get("ink", (0, 1))[0]
                                                        / max(q.get("ink", (0, 1))[1], 1))
                          for q in p["panels"])
        print("  %-32s %-11s %s" % (p["id"], p["kind"], marks))
    print("%s: %d plots, %d bytes, loaded in %.2f s%s, checked in %.1f s"
          % (args.report, len(parser.plots), os.path.getsize(path), loaded,
             "" if painted is None else ", whole page laid out and painted in %.2f s" % painted,
             time.monotonic() - started))
    if failures:
        for f in failures:
            print("FAIL: " + f)
        return 1
    print("OK")
    return 0


if __name__ == "__main__":
    sys.exit(main())
