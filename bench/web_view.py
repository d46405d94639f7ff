"""The live view's update rate and its latency from a Modbus write to the drawing.

Starts the soft PLC with the packaged controller (10 ms task, real time), the live view
(`armbench serve --web`'s server) on free loopback ports, and Debian's chromium headless
through Playwright. Another Modbus client then sends MoveJoints commands to alternating
targets; for each, the latency runs from just before its FC16 write (wall clock) to the first
frame the page drew with the new joint-move target (BaseDeg.., which the PLC sets in the scan
that takes the command; the drawn output stage then follows the motion), on the page's own
clock (performance.timeOrigin + performance.now(): the same machine's wall clock), split at
the server's read of the PLC that first saw it. The update rate is frames drawn per second,
counted in the page over a few seconds. A Python WebSocket client then reads the same stream
for as long: how fast the server alone delivers (its share of the latency). Each configured
rate (--rates) is measured in the same run. Prints figures; not a test. With --screenshot PATH
it also saves a picture of the page after a short drive, and with --trace-screenshot PATH one
of the trace panel over that drive (docs/web-view.md's come from `--screenshot
docs/figures/web-view.png --trace-screenshot docs/figures/web-trace.png`).

    .venv/bin/python bench/web_view.py [--rates 20 50 100] [--samples 40] [--seconds 5]
"""

from __future__ import annotations

import argparse
import json
import math
import os
import shutil
import statistics
import sys
import time
from pathlib import Path

try:
    from armbench.controller_client import ArmControllerClient
except ImportError:  # running from a checkout without `pip install -e .`
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "sim"))
    from armbench.controller_client import ArmControllerClient
from playwright.sync_api import Page, sync_playwright
from websockets.sync.client import connect

from armbench.controller_client import CMD_MOVE_JOINTS
from armbench.demo import RunningPlc, circle, serve_controller
from armbench.softplc.modbus_client import PlcClient
from armbench.web.app import WebView

TARGETS = ((10.0, 70.0, 65.0), (-15.0, 60.0, 80.0))
TRACED = ("OutBaseDeg", "OutShoulderDeg", "OutElbowDeg", "MotionKind", "MotionProgress")

FIND_FIRST = """([target, after]) => {
  const h = window.armbench.history;
  for (const d of h) {
    if (d.at >= after && d.target && d.target.every((v, i) => Math.abs(v - target[i]) < 1e-3))
      return d;
  }
  return null;
}"""


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[min(len(s) - 1, max(0, math.ceil(q / 100.0 * len(s)) - 1))]


def measure(page: Page, ctl: ArmControllerClient, web: WebView, samples: int,
            seconds: float) -> dict[str, float]:
    page.goto(web.url)
    page.wait_for_function("window.armbench.frames > 5", timeout=20000)
    f0 = page.evaluate("[window.armbench.frames, window.armbench.messages, performance.now()]")
    time.sleep(seconds)
    f1 = page.evaluate("[window.armbench.frames, window.armbench.messages, performance.now()]")
    dt = (f1[2] - f0[2]) / 1000.0
    frames_hz = (f1[0] - f0[0]) / dt
    total, to_server, to_page = [], [], []
    for i in range(samples):
        target = TARGETS[i % 2]
        time.sleep(0.05)  # let the page settle on the last target
        t_write = time.time()
        pending = ctl.submit(CMD_MOVE_JOINTS, args=target)
        assert ctl.wait(pending) == 0
        page.wait_for_function(f"arg => ({FIND_FIRST})(arg) !== null",
                               arg=[list(target), t_write * 1000.0], timeout=10000)
        d = page.evaluate(FIND_FIRST, [list(target), t_write * 1000.0])
        total.append(d["at"] - t_write * 1000.0)
        to_server.append(d["t"] * 1000.0 - t_write * 1000.0)
        to_page.append(d["at"] - d["t"] * 1000.0)
    return {"frames_hz": frames_hz, "messages_hz": (f1[1] - f0[1]) / dt,
            "poll_hz": web.monitor.snapshot().get("poll_hz") or 0.0,
            "lat_p50": statistics.median(total), "lat_p95": pct(total, 95),
            "lat_max": max(total), "srv_p50": statistics.median(to_server),
            "page_p50": statistics.median(to_page), "page_p95": pct(to_page, 95)}


def server_side(web: WebView, seconds: float) -> dict[str, float]:
    """The same stream read by a Python WebSocket client: the server's share of the time."""
    lat: list[float] = []
    with connect(web.url.replace("http", "ws") + "ws", open_timeout=10) as ws:
        t0 = time.time()
        while time.time() - t0 < seconds:
            snap = json.loads(ws.recv(timeout=5))
            lat.append((time.time() - snap["t"]) * 1000.0)
            ws.send("drawn")
    return {"ws_hz": len(lat) / seconds, "ws_p50": statistics.median(lat),
            "ws_p95": pct(lat, 95)}


def screenshot(page: Page, ctl: ArmControllerClient, web: WebView, path: Path,
               trace_path: Path | None) -> None:
    """The arm view after a drive by another client and a command the PLC rejects; with
    ``trace_path`` also the trace panel of the output stage over the same drive."""
    page.goto(web.url + "#arm")
    page.wait_for_function("window.armbench.frames > 5 && "
                           "document.querySelector('#cmdtabs button') !== null", timeout=20000)
    page.click("#cmdtabs button[data-group=Setup]")
    page.click("form[data-command=CmdInitPwm] button")
    page.wait_for_function("window.armbench.lastResult && window.armbench.lastResult.ok")
    page.click("#views button[data-view=trace]")
    page.wait_for_function("document.querySelector('#trace-vars input') !== null")
    for name in TRACED:
        page.check(f"#trace-vars input[value={name}]")
    page.select_option("#trace-window", "10")
    page.click("#views button[data-view=arm]")
    page.click("#cmdtabs button[data-group=Move]")
    ctl.move_joints(0.0, 70.0, 65.0, wait=True)
    for p in circle(24, (150.0, 0.0, 120.0), 40.0, "xy"):
        ctl.move_xyz(*p)
        time.sleep(0.06)
    ctl.move_linear((170.0, 30.0, 110.0), 60.0, 300.0, wait=True)
    form = "form[data-command=CmdMoveXyz]"
    page.fill(f"{form} input[name=x]", "400")
    page.fill(f"{form} input[name=z]", "0")
    page.click(f"{form} button")
    page.wait_for_function("document.getElementById('lastcmd').className === 'error'")
    page.fill(f"{form} input[name=x]", "150")
    page.fill(f"{form} input[name=z]", "120")
    time.sleep(1.5)
    page.evaluate("window.scrollTo(0, 0)")  # fill() scrolled the form into view
    path.parent.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(path))
    if trace_path is not None:
        page.click("#views button[data-view=trace]")
        page.wait_for_function("+document.getElementById('trace-plot').dataset.drawn > 0")
        page.click("#trace-pause")
        time.sleep(0.3)
        trace_path.parent.mkdir(parents=True, exist_ok=True)
        page.screenshot(path=str(trace_path))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[20.0, 50.0, 100.0],
                    help="server update rates to measure, Hz (20 50 100)")
    ap.add_argument("--samples", type=int, default=40, help="writes timed per rate (40)")
    ap.add_argument("--seconds", type=float, default=5.0, help="frame count window (5 s)")
    ap.add_argument("--screenshot", type=Path, default=None, help="save a screenshot here")
    ap.add_argument("--trace-screenshot", type=Path, default=None,
                    help="with --screenshot: save one of the trace panel here")
    a = ap.parse_args(argv)
    chromium = shutil.which("chromium")
    if chromium is None:
        print("chromium is not installed (Debian: apt-get install --no-install-recommends "
              "chromium; scripts/setup.sh does it as root)", file=sys.stderr)
        return 1
    rows = []
    with serve_controller() as running, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=chromium, args=["--no-sandbox"])
        page = browser.new_page(viewport={"width": 1300, "height": 1000})
        with PlcClient(running.host, running.port) as plc, ArmControllerClient(
                plc, poll_interval_s=0.0005) as ctl:
            for rate in a.rates:
                with WebView(running.host, running.port, web_port=0, rate_hz=rate,
                             local_plc=running.plc) as web:
                    r = measure(page, ctl, web, a.samples, a.seconds)
                    page.goto("about:blank")  # the Python client alone, next
                    r.update(server_side(web, a.seconds))
                    rows.append((rate, r))
            if a.screenshot is not None:
                with WebView(running.host, running.port, web_port=0,
                             local_plc=running.plc) as web:
                    screenshot(page, ctl, web, a.screenshot, a.trace_screenshot)
                print(f"screenshot: {a.screenshot}")
                if a.trace_screenshot is not None:
                    print(f"screenshot: {a.trace_screenshot}")
        browser.close()
        stats = next(iter(_stats(running).values()))
    load = os.getloadavg()
    print(f"live view, chromium headless, soft PLC 10 ms task ({stats}); "
          f"{a.samples} MoveJoints writes per rate; load average {load[0]:.1f} on "
          f"{os.cpu_count()} CPUs")
    print(f"{'rate Hz':>8} {'polls/s':>8} {'frames/s':>9} {'write->draw ms':>24} "
          f"{'write->read':>12} {'read->draw ms':>14} | {'Python ws client':>24}")
    print(f"{'':>8} {'':>8} {'':>9} {'p50    p95    max':>24} {'p50':>12} "
          f"{'p50    p95':>14} | {'msgs/s  read->recv p50 p95':>24}")
    for rate, r in rows:
        print(f"{rate:8g} {r['poll_hz']:8.1f} {r['frames_hz']:9.1f} "
              f"{r['lat_p50']:10.1f} {r['lat_p95']:6.1f} {r['lat_max']:6.1f} "
              f"{r['srv_p50']:12.1f} {r['page_p50']:7.1f} {r['page_p95']:6.1f} | "
              f"{r['ws_hz']:6.1f} {r['ws_p50']:12.1f} {r['ws_p95']:5.1f}")
    return 0


def _stats(running: RunningPlc) -> dict[str, str]:
    return {name: f"{s.scans} scans, {s.overruns} overruns"
            for name, s in running.plc.stats().items()}


if __name__ == "__main__":
    sys.exit(main())
