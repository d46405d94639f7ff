"""The live view of a program that is not the arm controller, and the trace, over Modbus.

tests/web/st/counter.st runs in the soft PLC; its located variables are known here from
OpenPLC's documented address map (written out below, not derived), and its values are
checked against a Modbus client of our own and against the program's own arithmetic
(Wave = SIN(Scans * 0.1) in float32), not against the view's output.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
import socket
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest
from webview_helpers import COUNTER, get, post, serve_program, wait_for

from armbench.demo import RunningPlc
from armbench.registermap import SOURCES, controller_map, program_map
from armbench.softplc import modbus_map as mm
from armbench.softplc.modbus_client import PlcClient
from armbench.web.app import WebView, parse_plc_address
from armbench.web.trace import MAX_VARIABLES, Trace
from armbench.web.variables import program_variables

# name: (location, Modbus table, first address, count) by OpenPLC v3's map: %QX/%IX bits
# byte * 8 + bit, %IW input register n, %MW 1024 + n, %MD 2048 + 2n, %ML 4096 + 4n.
EXPECTED = {
    "Wide": ("%ML0", "holding", 4096, 4), "Scans": ("%MD0", "holding", 2048, 2),
    "Wave": ("%MD1", "holding", 2050, 2), "Level": ("%MW0", "holding", 1024, 1),
    "Lamp": ("%QX0.0", "coil", 0, 1), "Hold": ("%MD2", "holding", 2052, 2),
    "Inp": ("%IW0", "input", 0, 1),
}


def wave(scans: int) -> float:
    """The program's Wave for a scan count as the PLC computes it: the REAL literal 0.1 makes
    C compute the product in double (MatIEC's C), SIN takes it rounded to float32."""
    arg = np.float32(float(np.float32(scans)) * 0.1)
    return float(np.float32(math.sin(float(arg))))


@pytest.fixture(scope="module")
def counter() -> Iterator[RunningPlc]:
    with serve_program([COUNTER]) as r:
        yield r


@pytest.fixture(scope="module")
def view(counter: RunningPlc) -> Iterator[WebView]:
    program = program_variables([COUNTER], "counter.st")
    with WebView(counter.host, counter.port, program=program, web_port=0,
                 local_plc=counter.plc) as w:
        wait_for(lambda: get(w, "api/state").get("connected") is True, "the view's first poll")
        yield w


def rows(w: WebView) -> dict[str, dict[str, Any]]:
    return {r["name"]: r for r in get(w, "api/registers")["registers"]}


def post_trace(w: WebView, body: object) -> tuple[int, Any]:
    return post(w, body, path="api/trace")


def test_program_map_lists_every_located_variable() -> None:
    pm = program_map([COUNTER])
    got = {r.name: (r.location, r.table, r.address, r.count) for r in pm.registers}
    assert got == EXPECTED
    assert [(u.name, u.location) for u in pm.unreachable] == [("Flag", "%MX0.0")]
    assert "not reachable over Modbus" in pm.unreachable[0].reason
    assert {r.name: r.description for r in pm.registers}["Wave"] == "SIN(Scans * 0.1)"
    # the controller's map is the same derivation
    controller = program_map(SOURCES)
    assert list(controller.registers) == list(controller_map().values())
    assert not controller.unreachable


def test_the_view_shows_and_updates_the_programs_variables(view: WebView,
                                                          counter: RunningPlc) -> None:
    info = get(view, "api/info")
    assert info["mode"] == "program" and info["program"] == "counter.st"
    assert info["variables"] == len(EXPECTED)
    assert [u["name"] for u in info["unreachable"]] == ["Flag"]
    s = get(view, "api/state")
    assert s["connected"] and s["mode"] == "program" and s["plc"]["state"] == "RUNNING"
    a = rows(view)
    assert {n: (r["location"], r["table"], r["address"]) for n, r in a.items()} == {
        n: e[:3] for n, e in EXPECTED.items()}
    assert a["Hold"]["value"] == 42.5 and a["Wide"]["value"] == 0.125
    assert a["Inp"]["value"] == 0 and a["Lamp"]["value"] in (True, False)
    assert a["Wave"]["value"] == pytest.approx(wave(a["Scans"]["value"]), abs=1e-6)
    assert 0 <= a["Level"]["value"] <= 99
    # a value another client writes shows at the next refresh
    with PlcClient(counter.host, counter.port) as plc:
        plc.write_registers(2052, list(mm.real_to_words(7.25)))
    wait_for(lambda: rows(view)["Hold"]["value"] == 7.25, "the written value in the table")
    b = rows(view)
    assert b["Scans"]["value"] > a["Scans"]["value"]
    assert b["Wave"]["value"] == pytest.approx(wave(b["Scans"]["value"]), abs=1e-6)
    # no commands for a program that is not the arm controller
    assert get(view, "api/commands")["commands"] == []
    status, answer = post(view, {"name": "CmdMoveXyz", "fields": {}})
    assert status == 400 and "not the arm controller" in answer["message"]


def test_trace_samples_are_timestamped_and_consistent(view: WebView,
                                                      counter: RunningPlc) -> None:
    status, answer = post_trace(view, {"variables": ["Scans", "Wave", "Lamp"]})
    assert status == 200 and answer["ok"], answer
    config = answer["config"]
    assert [v["name"] for v in answer["variables"]] == ["Scans", "Wave", "Lamp"]
    samples: list[list[Any]] = []

    def collect() -> bool:
        since = samples[-1][0] if samples else 0
        got = get(view, f"api/trace?since={since}&config={config}")
        assert got["config"] == config and got["error"] is None
        samples.extend(got["samples"])
        return len(samples) >= 300 and samples[-1][1] - samples[0][1] >= 1.0
    wait_for(collect, "a second of trace samples")
    seqs = [s[0] for s in samples]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # none lost, none twice
    times = [s[1] for s in samples]
    assert all(b > a for a, b in zip(times, times[1:], strict=False))
    assert abs(times[-1] - time.time()) < 5.0  # wall-clock seconds
    scans = [s[2] for s in samples]
    assert all(b >= a for a, b in zip(scans, scans[1:], strict=False))
    for s in samples:  # Scans and Wave come from one request: one scan's values
        assert s[3] == pytest.approx(wave(s[2]), abs=1e-6)
    assert {s[4] for s in samples} == {0, 1}  # BOOL as 0/1, both seen in a second
    # faster than the 10 ms scan: (nearly) every scan is seen, most more than once
    span_scans = scans[-1] - scans[0]
    assert len(samples) > span_scans
    assert len(set(scans)) >= 0.8 * (span_scans + 1)
    # the samples' times: a scan count our own client read at a known time was sampled by
    # the trace at about that time (a scan's values stand for one 10 ms period, longer on a
    # loaded machine)
    checks = 0
    with PlcClient(counter.host, counter.port) as plc:
        for _ in range(5):
            t_a = time.time()
            ours = mm.words_to_udint(plc.read_holding_registers(2048, 2))
            t_b = time.time()
            time.sleep(0.05)
            got = get(view, f"api/trace?since={samples[-1][0]}&config={config}")["samples"]
            samples.extend(got)
            at = [s[1] for s in samples if s[2] == ours]
            if at:
                checks += 1
                assert t_a - 0.25 < min(at) and max(at) < t_b + 0.25, (ours, t_a, t_b, at)
    assert checks >= 3

    text = urllib.request.urlopen(view.url + "api/trace.csv", timeout=10).read().decode()
    table = list(csv.reader(io.StringIO(text)))
    assert table[0] == ["time_s", "unix_time_s", "Scans", "Wave", "Lamp"]
    body = [[float(x) for x in r] for r in table[1:]]
    assert len(body) >= len(samples)
    assert body[0][0] == 0.0
    for r in body:
        assert r[1] - r[0] == pytest.approx(body[0][1], abs=1e-5)
        assert r[3] == pytest.approx(wave(int(r[2])), abs=1e-6)
        assert r[4] in (0.0, 1.0)


def test_trace_reconfigured_starts_again(view: WebView) -> None:
    status, first = post_trace(view, {"variables": ["Level"]})
    assert status == 200
    wait_for(lambda: len(get(view, "api/trace?since=0")["samples"]) > 5, "samples")
    status, second = post_trace(view, {"variables": ["Hold", "Wide", "Inp"]})
    assert status == 200 and second["config"] == first["config"] + 1
    got = get(view, f"api/trace?since=0&config={second['config']}")
    assert all(len(s) == 5 for s in got["samples"])
    wait_for(lambda: len(get(view, "api/trace?since=0")["samples"]) > 5, "new samples")
    s = get(view, "api/trace?since=0")["samples"][-1]
    assert s[3:] == [0.125, 0]
    status, third = post_trace(view, {"variables": []})
    assert status == 200 and third["variables"] == []


@pytest.mark.parametrize("body, message", [
    ({"variables": ["Nope"]}, "Nope is not a located variable of counter.st"),
    ({"variables": ["Flag"]}, "%MX0.0 is not reachable over Modbus"),
    ({"variables": ["Scans"] * (MAX_VARIABLES + 1)}, f"at most {MAX_VARIABLES} variables"),
    ({"variables": "Scans"}, "takes a list of variable names"),
    ({"variables": [1]}, "takes a list of variable names"),
    ([1], "must be a JSON object"),
])
def test_bad_trace_requests(view: WebView, body: object, message: str) -> None:
    status, answer = post_trace(view, body)
    assert status == 400 and message in answer["message"], answer


def test_bad_trace_query(view: WebView) -> None:
    req = urllib.request.Request(view.url + "api/trace?since=abc")
    with pytest.raises(urllib.error.HTTPError) as e:
        urllib.request.urlopen(req, timeout=10)
    assert e.value.code == 400 and "since must be a whole number" in json.load(e.value)["message"]


@pytest.mark.parametrize("text, expected", [
    ("127.0.0.1:5020", ("127.0.0.1", 5020)), ("plc.local", ("plc.local", 502)),
    ("[::1]:1502", ("::1", 1502)), ("[fe80::1]", ("fe80::1", 502))])
def test_plc_address(text: str, expected: tuple[str, int]) -> None:
    assert parse_plc_address(text) == expected


@pytest.mark.parametrize("text, message", [
    ("host:", "is not a number"), (":502", "has no host"), ("host:70000", "not 1..65535"),
    ("::1", "IPv6 address goes in brackets"), ("[::1", "give HOST:PORT")])
def test_bad_plc_address(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=re.escape(message)):
        parse_plc_address(text)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _live_view(argv: list[str]) -> tuple[subprocess.Popen[str], str, list[str]]:
    """Start `armbench ARGV`; its live view's URL and the lines it printed up to it."""
    proc = subprocess.Popen([sys.executable, "-m", "armbench.cli", *argv],
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert proc.stdout is not None
    lines: list[str] = []
    while True:
        line = proc.stdout.readline()
        if not line:
            proc.wait(10)
            err = proc.stderr.read() if proc.stderr else ""
            raise AssertionError(f"no live view: {lines} {err}")
        lines.append(line)
        m = re.search(r"live view .*on (http://\S+/)", line)
        if m:
            return proc, m.group(1), lines


def _json(url: str) -> Any:
    return json.load(urllib.request.urlopen(url, timeout=10))


def test_cli_serve_web_with_another_program() -> None:
    """`armbench serve --web my_program.st`: the page connects and shows its variables."""
    proc, url, lines = _live_view(["serve", "--web", "--no-library", str(COUNTER), "--port",
                                   "0", "--web-port", str(_free_port()), "--duration", "30"])
    try:
        wait_for(lambda: _json(url + "api/state")["connected"] is True, "the view to connect")
        regs = {r["name"]: r["value"] for r in _json(url + "api/registers")["registers"]}
        assert regs["Hold"] == 42.5 and regs["Scans"] > 0
        assert ": counter.st, 7 located variables" in lines[-1]
    finally:
        proc.terminate()
        proc.wait(10)


def test_cli_web_attaches_to_a_plc_by_address(counter: RunningPlc) -> None:
    """`armbench web --plc HOST:PORT --program FILE`: a view of a PLC it did not start."""
    proc, url, lines = _live_view(["web", "--plc", f"{counter.host}:{counter.port}",
                                   "--program", str(COUNTER), "--no-library", "--web-port",
                                   "0", "--duration", "30"])
    try:
        assert f"of {counter.host}:{counter.port}: counter.st" in lines[-1]
        wait_for(lambda: _json(url + "api/state")["connected"] is True, "the view to connect")
        info = _json(url + "api/info")
        assert info["mode"] == "program" and info["local_plc"] is False
        with PlcClient(counter.host, counter.port) as plc:
            before = mm.words_to_udint(plc.read_holding_registers(2048, 2))
        wait_for(lambda: {r["name"]: r["value"] for r in _json(url + "api/registers")[
            "registers"]}["Scans"] > before, "Scans to count on in the view")
    finally:
        proc.terminate()
        proc.wait(10)


def test_cli_web_without_program_names_what_is_wrong(counter: RunningPlc) -> None:
    """Attached as to the arm controller, a PLC that runs another program is named as such
    (and the view sends it no command) instead of a page that waits without a word."""
    proc, url, _ = _live_view(["web", "--plc", f"{counter.host}:{counter.port}",
                               "--web-port", "0", "--duration", "30"])
    try:
        wait_for(lambda: bool(_json(url + "api/state").get("waiting")), "the view's verdict")
        state = _json(url + "api/state")
        assert state["connected"] and "does not look like the arm controller" in \
            state["waiting"] and "--program" in state["waiting"]
        req = urllib.request.Request(url + "api/command", json.dumps(
            {"name": "CmdInitPwm", "fields": {}}).encode(), {"Content-Type": "application/json"})
        with pytest.raises(urllib.error.HTTPError) as e:
            urllib.request.urlopen(req, timeout=10)
        assert e.value.code == 409 and "does not look like the arm controller" in json.load(
            e.value)["message"]
    finally:
        proc.terminate()
        proc.wait(10)


@pytest.mark.parametrize("argv, option", [
    (["web"], "--plc"), (["web", "--plc", "host:0"], "--plc"),
    (["web", "--plc", "h:1", "--trace-period", "-1"], "--trace-period"),
    (["serve", "--web", "--trace-period", "nan"], "--trace-period")])
def test_cli_web_usage_errors(argv: list[str], option: str,
                              capsys: pytest.CaptureFixture[str]) -> None:
    from armbench.cli import main

    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and option in err[0], err


def test_trace_ring_and_idle_pause(counter: RunningPlc) -> None:
    """The ring keeps the newest samples (a page that fell behind is told how many it lost),
    and nobody fetching for idle_s pauses the sampling until the next fetch."""
    program = program_variables([COUNTER], "counter.st")
    trace = Trace(counter.host, counter.port, program, min_period_s=0.002, keep=100,
                  idle_s=0.5)
    trace.start()
    try:
        trace.configure(["Scans"])
        wait_for(lambda: trace.samples(0)["samples"][-1:] != []
                 and trace.samples(0)["samples"][0][0] > 150, "the ring to overflow")
        got = trace.samples(1)
        assert got["lost"] == got["samples"][0][0] - 2 and len(got["samples"]) <= 125
        seqs = [s[0] for s in got["samples"]]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))
        time.sleep(1.0)  # no fetch: idle after 0.5 s
        last = trace.samples(0)  # this fetch wakes it
        assert last["idle"] is True
        t_last = last["samples"][-1][1]
        assert time.time() - t_last > 0.3  # nothing sampled for the last half second or so
        wait_for(lambda: trace.samples(0)["samples"][-1][1] > t_last + 0.1, "sampling again")
        assert trace.samples(0)["idle"] is False
    finally:
        trace.stop()
